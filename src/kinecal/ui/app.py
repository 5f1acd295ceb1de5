"""The workbench: viser's server and the page's own (`kinecal.ui.front`), the model box
and the four views (See, Plan, Run, Check) over one `kinecal.ui.session.Session`.

Both servers listen on 127.0.0.1 only. viser calls the views back on threads of its own;
work longer than a redraw (a calibration, a pose selection) runs in a worker process
(`kinecal.ui.runs`), so that the page answers while it runs.
"""

from __future__ import annotations

import contextlib
import html
import io
import threading
from collections.abc import Sequence
from pathlib import Path

from kinecal.errors import InputError
from kinecal.ui.front import FrontServer
from kinecal.ui.session import Session, error_text

__all__ = ["Workbench"]

#: the model box's first entry: no model chosen yet
NO_MODEL = "(choose a model)"


def _bundled_models() -> list[str]:
    from kinecal.io.models import bundled_models

    return list(bundled_models())


def _bundled_data(model_name: str | None) -> list[str]:
    """``NAME:PART`` of the bundled measurement sets of `model_name`."""
    from kinecal.datasets import DATASETS

    out = []
    for name, info in DATASETS.items():
        if info.get("model") == model_name:
            out += [f"{name}:{part}" for part, file in info["parts"].items()
                    if file.endswith(".csv")]
    return out


class Workbench:
    """A running workbench (module docstring).

    Parameters
    ----------
    model : str, optional
        MODEL as the command line takes it: a bundled name, a model YAML, a system file or
        a URDF.
    data : sequence of str
        Measurement files (or bundled ``NAME:PART``); the first is calibrated, a second is
        offered as validation.
    port : int
        Port of the page on 127.0.0.1 (0: any free port).
    db : str, optional
        The registry (a SQLite path or a ``postgresql://`` URL) of the Check view.
    workdir : Path
        Where the page writes its files (runs, plans, dropped files).
    tip_links : sequence of str
        ``--tip-link`` of a URDF model (several: a system).
    """

    def __init__(self, model: str | None = None, data: Sequence[str] = (), *, port: int = 8080,
                 db: str | None = None, workdir: str | Path = "kinecal-ui",
                 base_link: str | None = None, tip_links: Sequence[str] = ()) -> None:
        import viser

        self.session = Session(Path(workdir), base_link=base_link, tip_links=list(tip_links))
        self.db = db
        with contextlib.redirect_stdout(io.StringIO()):  # viser's banner names its own port
            self.server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
        self.server.gui.configure_theme(control_width="large", dark_mode=False,
                                        show_logo=False)
        self.server.scene.set_up_direction("+z")
        try:
            self.front = FrontServer(port, self.server.get_port(), self._dropped)
        except InputError:
            self.server.stop()
            raise
        self._busy = threading.Lock()
        self._build()
        try:
            if model is not None:
                self.load(model)
            for spec in data:
                self.load(spec)
        except BaseException:
            self.close()
            raise

    @property
    def url(self) -> str:
        """The page's address (http://127.0.0.1:PORT/)."""
        return self.front.url

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        from kinecal.ui.check import CheckView
        from kinecal.ui.plan import PlanView
        from kinecal.ui.run import RunView
        from kinecal.ui.see import SeeView

        gui = self.server.gui
        self.model_box = gui.add_dropdown("Model", (NO_MODEL, *_bundled_models()),
                                          initial_value=NO_MODEL,
                                          hint="A bundled robot; or drop a model file (YAML, "
                                          "URDF) on the page")
        self.bundled = gui.add_dropdown("Bundled data", ("(none)",), initial_value="(none)",
                                        hint="Measurements bundled with kinecal for this "
                                        "model")
        self.upload = gui.add_upload_button("Open file...", hint="A model, measurements, a "
                                            "plan or a result (or drop files on the page)")
        self.status = gui.add_html(_status_html(True, "Choose a model, or drop files on the "
                                                "page."))
        tabs = gui.add_tab_group()
        self.see = SeeView(self, tabs.add_tab("See"))
        self.plan = PlanView(self, tabs.add_tab("Plan"))
        self.run = RunView(self, tabs.add_tab("Run"))
        self.check = CheckView(self, tabs.add_tab("Check"))
        self.model_box.on_update(self._model_chosen)
        self.bundled.on_update(self._bundled_chosen)
        self.upload.on_upload(lambda ev: self._dropped(self.upload.value.name,
                                                       self.upload.value.content))

    # ------------------------------------------------------------------ loading
    def say(self, ok: bool, text: str) -> None:
        """Show one line in the status box (an error in red)."""
        self.status.content = _status_html(ok, text)

    def load(self, spec: str) -> str:
        """Load a model, measurement, plan or result file by its argument (the command
        line's form); returns what was loaded. Raises `InputError` as the CLI would."""
        s = self.session
        suffix = Path(spec).suffix.lower()
        if suffix == ".json":
            s.require_model()
            return self.run.add_result_file(spec)
        if suffix == ".csv" or (":" in spec and not suffix and not Path(spec).exists()):
            message = s.load_file(spec)
            self._changed()
            return message
        message = s.set_model(spec)
        if spec in self.model_box.options:
            self.model_box.value = spec
        self.bundled.options = ("(none)", *_bundled_data(s.model.name))
        self.bundled.value = "(none)"
        self.see.set_result(None)
        self.run.model_changed()
        self._changed()
        return message

    def _changed(self) -> None:
        self.see.refresh()
        self.plan.refresh()
        self.run.refresh()
        self.check.refresh()

    def _model_chosen(self, _event) -> None:
        name = self.model_box.value
        if name == NO_MODEL or name == self.session.model_spec:
            return
        self._guarded(lambda: self.load(name))

    def _bundled_chosen(self, _event) -> None:
        spec = self.bundled.value
        if spec == "(none)" or spec in self.session.data:
            return
        self._guarded(lambda: self.load(spec))

    def _guarded(self, action) -> tuple[bool, str]:
        try:
            with self._busy:
                message = action()
        except InputError as exc:
            message = error_text(exc)
            self.say(False, message)
            return False, message
        self.say(True, message)
        return True, message

    def _dropped(self, name: str, content: bytes) -> tuple[bool, str]:
        """A file dropped on the page (or opened with the button): kept under the working
        folder and loaded like a command-line argument."""
        try:
            path = self.session.save_dropped(name, content)
        except OSError as exc:
            message = f"kinecal: error: {name}: cannot keep the dropped file: {exc.strerror}"
            self.say(False, message)
            return False, message
        return self._guarded(lambda: self.load(str(path)))

    def close(self) -> None:
        """Stop the runs, then both servers."""
        self.run.stop_all()
        self.front.close()
        self.server.stop()


def _status_html(ok: bool, text: str) -> str:
    color = "#1b5e20" if ok else "#8e1b12"
    return (f'<div id="kc-status" class="{"kc-ok" if ok else "kc-error"}" style="font-size:'
            f'12px;padding:0 8px;color:{color};white-space:pre-wrap">{html.escape(text)}</div>')
