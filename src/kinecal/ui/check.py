"""The Check view: with ``--db``, the registry's robots (``kinecal registry list``), a
robot's history and drift (``kinecal registry history``: the records, the drift rates and
the figure of its checks) and a check of a few poses measured today against its current
calibration, run by the command line (``kinecal check SERIAL FILES --db DB``) in a worker
process like every calibration of the page (`kinecal.ui.runs`).

The page reads the registry read-only (`kinecal.registry.open_registry`, opened and closed
at each reading); only the command line's check writes to it. Without the registry (a
kinecal without `kinecal.registry`, or without its extra) or without ``--db`` the view
says so in one line and offers nothing else.
"""

from __future__ import annotations

import html
import json

from kinecal.errors import InputError
from kinecal.ui.runs import Run
from kinecal.ui.session import error_text

__all__ = ["CheckView", "registry_available"]

#: the view's line when this kinecal has no registry
NO_REGISTRY = ("This kinecal has no registry (kinecal registry, kinecal check): the Check "
               "view needs it.")
#: what ``kinecal check`` exits with for each verdict (0, 3, 4; 2 is bad input)
VERDICT_CODES = (0, 3, 4)
NONE = "(none)"


def registry_available() -> bool:
    """Whether this kinecal has the registry (`kinecal.registry`)."""
    import importlib.util

    return importlib.util.find_spec("kinecal.registry") is not None


class CheckView:
    """The Check tab (module docstring); `app` is the `kinecal.ui.app.Workbench`."""

    def __init__(self, app, tab) -> None:
        self.app = app
        self.db = app.db
        self.rows: list[dict] = []
        self.checking: Run | None = None
        gui = app.server.gui
        with tab:
            self.info = gui.add_html("")
            self.usable = self.db is not None and registry_available()
            if not self.usable:
                self._say(NO_REGISTRY if self.db is not None else
                          "Start the workbench with --db DB (a SQLite file or a "
                          "postgresql:// URL) to see the registry's robots, their history "
                          "and drift, and to check one.")
                return
            self.robot = gui.add_dropdown("Robot", (NONE,), initial_value=NONE,
                                          hint="A serial number of the registry")
            self.reload = gui.add_button("Reload the registry")
            self.fleet = gui.add_html("")
            self.history = gui.add_html("")
            with gui.add_folder("Check today's poses"):
                self.files = gui.add_dropdown("Measurements", (NONE,), initial_value=NONE,
                                              hint="A file loaded in the page (drop one)")
                self.limit = gui.add_number("Limit (0: the default)", 0.0, min=0.0,
                                            step=0.01, hint="Largest acceptable systematic "
                                            "error, RMS per pose (length unit); default "
                                            "twice the calibration's RMS error")
                self.start = gui.add_button("Check", color="green")
                self.outcome = gui.add_html("")
        self.robot.on_update(lambda _: self._guard(self.show_robot))
        self.reload.on_click(lambda _: self._guard(self.load))
        self.start.on_click(lambda _: self.app._guarded(self.check))
        self._guard(self.load)

    # ------------------------------------------------------------------ reading
    def _say(self, text: str, error: bool = False) -> None:
        color = "#8e1b12" if error else "inherit"
        self.info.content = (f'<div id="kc-check" style="font-size:12px;padding:0 8px;'
                             f'color:{color};white-space:pre-wrap">{html.escape(text)}</div>')

    def _guard(self, action) -> None:
        try:
            action()
        except InputError as exc:
            self._say(error_text(exc), error=True)

    def _open(self):
        from kinecal.registry import open_registry

        return open_registry(self.db, write=False)

    def load(self) -> None:
        """Read the robots and show the chosen one's history."""
        with self._open() as reg:
            self.rows = reg.robots()
            where = reg.location.shown
        serials = tuple(r["serial"] for r in self.rows) or (NONE,)
        self._say(f"registry {where}: {len(self.rows)} robot(s)")
        self.fleet.content = _fleet_table(self.rows)
        if tuple(self.robot.options) != serials:
            self.robot.options = serials
        if self.robot.value not in serials:
            self.robot.value = serials[0]
        self.show_robot()

    def refresh(self) -> None:
        """The page's files changed: offer them to the check."""
        if not self.usable:
            return
        names = tuple(self.app.session.data) or (NONE,)
        if tuple(self.files.options) != names:
            self.files.options = names
            self.files.value = names[-1]

    def show_robot(self) -> None:
        """The chosen robot's history in words and its drift figure."""
        from kinecal.registry.drift import drift_summary
        from kinecal.registry.figures import history_figure
        from kinecal.registry.views import history_text

        serial = self.robot.value
        if serial == NONE:
            self.history.content = ""
            return
        with self._open() as reg:
            hist = reg.history(serial)
        drift = drift_summary(hist)
        folder = self.app.session.workdir / "check"
        folder.mkdir(parents=True, exist_ok=True)
        n = len(hist["events"])
        png = history_figure(hist, drift, folder / f"{_safe(serial)}-{n}.png")
        url = self.app.front.publish(f"check/{png.name}", png)
        self.history.content = (
            f'<div id="kc-history" style="font-size:11px;padding:0 8px;white-space:pre;'
            f'overflow-x:auto;font-family:monospace">{html.escape(history_text(hist, drift))}'
            f'</div><img id="kc-drift" src="{url}" alt="checks of {html.escape(serial)} '
            'over time" style="width:100%;padding:4px 0">')

    # ------------------------------------------------------------------ checking
    def check(self) -> str:
        """``kinecal check SERIAL FILE --db DB --json`` in a worker process."""
        serial = self.robot.value
        if serial == NONE:
            raise InputError("the registry has no robot to check")
        ds = self.app.session.data.get(self.files.value)
        if ds is None:
            raise InputError("no measurements to check with: load or drop a file first")
        if self.checking is not None and self.checking.running:
            raise InputError("a check is running: wait for it")
        folder = self.app.session.workdir / "check"
        args = ["check", serial, ds.spec, "--db", self.db, "--json"]
        if float(self.limit.value) > 0:
            args += ["--limit", f"{float(self.limit.value):.17g}"]
        run = Run(f"check of {serial}", args, folder, on_change=self._checked,
                  ok_codes=VERDICT_CODES)
        self.checking = run.start()
        return f"checking {serial}: {run.command}"

    def _checked(self, run: Run) -> None:
        if run.running:
            self.outcome.content = _box(f"{run.label}: running ({run.seconds:.1f} s)\n"
                                        f"$ {run.command}")
            return
        if run.status != "done":
            text = run.error or f"{run.label} {run.status}"
            self.outcome.content = _box(text, error=True)
            self.app.say(False, text)
            return
        doc = json.loads(run.stdout)
        unit = doc.get("length_unit", "")
        text = (f"{doc['serial']}: {doc['verdict'].upper()} (check {doc['id']}, of calibration "
                f"{doc['calibration']}): systematic error {doc['deviation']:.4g} {unit} RMS "
                f"per pose, limit {doc['limit']:.4g} {unit}; p = {doc['p_value']:.3g}")
        self.outcome.content = _box(text + f"\n$ {run.command}")
        self.app.say(True, text)
        self._guard(self.load)


def _fleet_table(rows: list[dict]) -> str:
    head = ("<tr><th>serial</th><th>model</th><th>cal.</th><th>checks</th><th>current</th>"
            "<th>last check</th></tr>")
    body = "".join(
        f"<tr><td>{html.escape(r['serial'])}</td><td>{html.escape(r['model'] or '-')}</td>"
        f"<td>{r['calibrations']}</td><td>{r['checks']}</td>"
        f"<td>{html.escape(str(r['current']['id']) if r['current'] else '-')}</td>"
        f"<td>{html.escape(r['last_check']['verdict'] if r['last_check'] else '-')}</td>"
        "</tr>" for r in rows)
    return f'<table id="kc-fleet" style="font-size:12px;margin:0 8px">{head}{body}</table>'


def _safe(serial: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in serial) or "robot"


def _box(text: str, error: bool = False) -> str:
    color = "#8e1b12" if error else "inherit"
    return (f'<div id="kc-check-outcome" style="font-size:12px;padding:0 8px;'
            f'white-space:pre-wrap;color:{color}">{html.escape(text)}</div>')

