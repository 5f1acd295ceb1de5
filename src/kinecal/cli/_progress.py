"""Progress on stderr where users wait: a bar with a count (`progress`) or a transient line
with the time so far (`status`), both silent under ``--quiet`` and when stderr is not a
terminal (`quiet_requested`). Rich is imported only when a bar is shown."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator

__all__ = ["progress", "progress_columns", "quiet_requested", "status"]


def quiet_requested(quiet: bool) -> bool:
    """True when progress bars must stay off (asked for, or stderr is not a terminal)."""
    return quiet or not sys.stderr.isatty()


def progress_columns(total: int | None) -> list:
    """The columns of a progress bar: ``done/total`` when the total is known, else the
    count of steps done alone (an iteration count with no budget: never ``19/None``)."""
    from rich.progress import BarColumn, TextColumn, TimeElapsedColumn

    count = "{task.completed}/{task.total}" if total is not None else "{task.completed} it."
    return [TextColumn("[bold]{task.description}"), BarColumn(), TextColumn(count),
            TextColumn("{task.fields[best]}"), TimeElapsedColumn()]


@contextlib.contextmanager
def progress(
    description: str, total: int | None, quiet: bool = False
) -> Iterator[Callable[..., None]]:
    """Context manager yielding ``update(advance=1, best=None)`` that drives a rich bar.

    The bar goes to stderr and is silent when `quiet` or stderr is not a terminal.
    """
    if quiet_requested(quiet):
        yield lambda advance=1, best=None: None
        return
    from rich.console import Console
    from rich.progress import Progress

    with Progress(*progress_columns(total), console=Console(stderr=True),
                  transient=True) as bar:
        task = bar.add_task(description, total=total, best="")

        def update(advance: int = 1, best: float | None = None) -> None:
            fields = {} if best is None else {"best": f"best {best:.4g}"}
            bar.update(task, advance=advance, **fields)

        yield update


@contextlib.contextmanager
def status(description: str, quiet: bool = False) -> Iterator[None]:
    """A transient line on stderr (a spinner, `description` and the time so far) while the
    block runs: a step that takes seconds without a count (a report rendered, a PDF laid
    out). Silent like `progress`: under `quiet` or when stderr is not a terminal."""
    if quiet_requested(quiet):
        yield
        return
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=Console(stderr=True), transient=True) as bar:
        bar.add_task(description, total=None)
        yield
