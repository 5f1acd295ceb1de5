"""The write tail every command shares: its output files written together, or none.

A command that writes a result JSON, a model (or geometry) file and a report calls
`write_outputs` once, after its work, with each output and the function that writes it.
Every file goes to a temporary file first (`kinecal._files.all_or_nothing`); only when the
last one (a report whose PDF takes seconds to render) is written and synced are they all
renamed over their targets. A failed run (a full disk, ``ulimit -f``, Ctrl-C while a PDF
renders, ``--report`` linked to ``/dev/full``) leaves every earlier output as it was, and
no new file behind. While a file is written a transient line on stderr says which
(`kinecal.cli._common.status`); under ``SOURCE_DATE_EPOCH`` a result JSON carries no time
a run took (``"seconds": null``: `kinecal.cli._common.without_times`), so that two runs
give the same bytes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from kinecal.cli._common import status, write_json

__all__ = ["write_outputs"]

def write_outputs(*, out: Path | None = None, result: Any = None,
                  model_out: Path | None = None, save_model: Callable[[Path], Any] | None = None,
                  report: Path | None = None, write_report: Callable[[Path], Any] | None = None,
                  more: Sequence[tuple[Path | None, Callable[[Path], Any]]] = (),
                  quiet: bool = False) -> None:
    """Write a command's outputs all together or not at all (module docstring).

    Parameters
    ----------
    out, result
        ``--out`` and the result dictionary written there as JSON.
    model_out, save_model
        ``--model-out`` and the function that writes the model file to a path.
    report, write_report
        ``--report`` and the function that writes the report (HTML or PDF) to a path.
    more : sequence of (path, writer)
        Further outputs (``--geometry-out``, ``--truth-out``...), each written by
        ``writer(path)``.
    quiet : bool
        No progress line (``--quiet``, ``--json``).

    Outputs whose path is None are not written. Each writer must write through
    `kinecal._files` (`atomic_open`, `write_text_atomic`...), as every kinecal writer does.
    """
    from kinecal._files import all_or_nothing

    todo = [(out, lambda p: write_json(p, result)), (model_out, save_model),
            (report, write_report), *more]
    todo = [(Path(p), w) for p, w in todo if p is not None]
    if not todo:
        return
    with all_or_nothing():
        for path, write in todo:
            if write is None:
                raise ValueError(f"no writer given for {path}")
            with status(f"writing {path}", quiet):
                write(path)
