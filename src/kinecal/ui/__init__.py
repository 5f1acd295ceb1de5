"""The workbench: kinecal in the browser (``kinecal ui``; docs/workbench.md).

A local web page over the same engine as the command line, in four views: **See** (the
robot, its measured poses and their errors before and after calibration, the instruments
where the calibration put them), **Plan** (poses by hand or by ``select-poses``, what they
identify at once, robot programs), **Run** (calibrations by the command line in a worker
process, what the poses identify in words, reports, two results side by side) and
**Check** (the registry of ``--db``).

Built on viser (Yi et al., "Viser: Imperative, Web-based 3D Visualization in Python",
2025), whose client is bundled in its wheel: the page needs no network. Served on
127.0.0.1 only.

Entry points: `Workbench` (`kinecal.ui.app`), `serve`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from kinecal.ui.app import Workbench

__all__ = ["Workbench", "serve"]


def __getattr__(name: str):
    if name == "Workbench":
        from kinecal.ui.app import Workbench

        return Workbench
    raise AttributeError(name)


def serve(model=None, data=(), *, port: int = 8080, db=None, open_browser: bool = True,
          base_link=None, tip_links=(), workdir="kinecal-ui", echo=print) -> None:
    """Run a `Workbench` until interrupted (Ctrl-C), opening the page in the browser."""
    import time

    from kinecal.ui.app import Workbench

    bench = Workbench(model, data, port=port, db=db, workdir=workdir, base_link=base_link,
                      tip_links=tip_links)
    echo(f"kinecal workbench at {bench.url} (Ctrl-C stops it)")
    if open_browser:
        import webbrowser

        webbrowser.open(bench.url)
    try:
        while True:
            time.sleep(3600)
    finally:
        bench.close()
