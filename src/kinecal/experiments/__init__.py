"""Paper reproductions: one module per paper, each exposing the same two functions.

``run(quick=False, seed=0, out_dir=None, quiet=True) -> dict``
    Runs the paper's experiment and returns a JSON-able dict with at least
    ``{"paper": id, "rows": [...]}`` (errors in the paper's units, stated in the dict).
    Figures (PNG) go to `out_dir` when given.
``render(result: dict) -> str``
    The table as text, the paper's published values beside kinecal's.
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["PAPERS", "experiment_module"]

#: paper id -> (module, the paper as output and docs name it: authors, year)
PAPERS: dict[str, tuple[str, str]] = {
    "hu2005": ("kinecal.experiments.hu2005", "Hu, Xiao and Li (2005)"),
    "li2024": ("kinecal.experiments.li2024", "Li, Xiao, Lai and Hu (2024)"),
    "zhao-yang": ("kinecal.experiments.zhao_yang", "Zhao and Yang"),
    "liu2008": ("kinecal.experiments.liu2008", "Liu, Liu and Wei (2008)"),
}


def experiment_module(paper: str) -> ModuleType:
    """Import the experiment module of `paper` (an id of `PAPERS`)."""
    from kinecal.errors import InputError

    if paper not in PAPERS:
        raise InputError(
            f"unknown paper {paper!r}; expected one of {', '.join(PAPERS)}", option="PAPER"
        )
    return importlib.import_module(PAPERS[paper][0])
