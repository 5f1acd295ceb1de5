"""The Check view: with ``--db``, the registry's robots, each one's history and drift
plot, and a check of a few measured poses against its current calibration (``kinecal
check``, run by the command line in a worker process).

It shows what the installed kinecal has: without the registry package
(`kinecal.registry`) or without ``--db`` it says so and offers nothing else.
"""

from __future__ import annotations

import html

__all__ = ["CheckView"]


def registry_available() -> bool:
    """Whether this kinecal has the registry (`kinecal.registry`)."""
    import importlib.util

    return importlib.util.find_spec("kinecal.registry") is not None


class CheckView:
    """The Check tab (module docstring)."""

    def __init__(self, app, tab) -> None:
        self.app = app
        gui = app.server.gui
        with tab:
            self.info = gui.add_html("")
        if app.db is None:
            text = ("Start the workbench with --db DB (a SQLite file or a postgresql:// URL) "
                    "to see the registry's robots, their history and drift, and to check "
                    "one.")
        elif not registry_available():
            text = "This kinecal has no registry (kinecal registry): nothing to show."
        else:
            text = f"registry: {app.db}"
        self.info.content = (f'<div id="kc-check" style="font-size:12px;padding:0 8px">'
                             f"{html.escape(text)}</div>")
