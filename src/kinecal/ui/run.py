"""The Run view: calibrate with progress, by the command line itself in a worker process
(`kinecal.ui.runs`); what the poses identify, in words; the HTML report opened over the
page; two results side by side.

Each run writes into ``kinecal-ui/run-K/`` (``result.json``, ``report.html``) and shows
the exact command, so that it can be repeated without the page.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinecal.errors import InputError
from kinecal.ui.runs import Run, calibrate_args

__all__ = ["RunView", "identifiability_words"]

#: the methods offered (every method of ``kinecal calibrate --method`` works on the CLI)
METHODS = ("lm", "householder", "hybrid-gwo", "pso", "ga", "de", "gwo")
NONE = "(none)"


@dataclass
class Outcome:
    """A finished calibration: its run (None for a result file opened) and result."""

    label: str
    folder: Path | None
    data: dict
    params: np.ndarray | None
    run: Run | None = None

    @property
    def report(self) -> Path | None:
        if self.folder is None:
            return None
        path = self.folder / "report.html"
        return path if path.is_file() else None


def identifiability_words(data: dict) -> str:
    """What a result's poses identify, as sentences (from its JSON)."""
    free, unident = data.get("free") or [], data.get("unidentifiable") or []
    n = len(free) + len(unident)
    words = [f"These measurements identify {data.get('rank', len(free))} of the {n} "
             f"parameters examined (condition number {data.get('condition_number', 0):.3g})."]
    if unident:
        words.append("Held at nominal, because the poses cannot tell them apart from "
                     "others:")
        conf = data.get("confounded_with") or {}
        for name in unident:
            parts = conf.get(name) or {}
            if parts:
                combo = " ".join(f"{c:+.3g}*{other}" for other, c in parts.items())
                words.append(f"  {name}: moves the tool exactly as {combo}.")
            else:
                words.append(f"  {name}: has no effect on what was measured.")
    else:
        words.append("Every parameter examined is identified.")
    return "\n".join(words)


class RunView:
    """The Run tab (module docstring)."""

    def __init__(self, app, tab) -> None:
        self.app = app
        gui = app.server.gui
        self.outcomes: list[Outcome] = []
        self.runs: list[Run] = []
        with tab:
            self.data = gui.add_dropdown("Calibrate on", (NONE,), initial_value=NONE)
            self.validate = gui.add_dropdown("Validate on", (NONE,), initial_value=NONE)
            self.method = gui.add_dropdown("Method", METHODS, initial_value="lm")
            self.start = gui.add_button("Calibrate", color="green", disabled=True)
            self.stop = gui.add_button("Stop", disabled=True)
            self.progress = gui.add_progress_bar(0.0, animated=False)
            self.status = gui.add_html(_box("kc-run", "No run yet."))
            self.words = gui.add_html("")
            with gui.add_folder("Compare two results"):
                self.left = gui.add_dropdown("Left", (NONE,), initial_value=NONE)
                self.right = gui.add_dropdown("Right", (NONE,), initial_value=NONE)
                self.compare = gui.add_html("")
        self.start.on_click(lambda _: self.app._guarded(self.calibrate))
        self.stop.on_click(lambda _: self.stop_all())
        for box in (self.left, self.right):
            box.on_update(lambda _: self._compare())

    # ------------------------------------------------------------------ state
    def model_changed(self) -> None:
        self.outcomes.clear()
        self._lists()

    def refresh(self) -> None:
        s = self.app.session
        names = tuple(s.data) or (NONE,)
        if tuple(self.data.options) != names:
            self.data.options = names
            self.validate.options = (NONE, *s.data)
            self.data.value = names[0]
            self.validate.value = (list(s.data)[1] if len(s.data) > 1 else NONE)
        self.start.disabled = s.model is None or not s.data or any(r.running for r in self.runs)

    def _lists(self) -> None:
        labels = tuple(o.label for o in self.outcomes) or (NONE,)
        for box, pick in ((self.left, -2), (self.right, -1)):
            box.options = labels
            box.value = labels[pick] if len(labels) >= -pick else labels[-1]
        self._compare()

    # ------------------------------------------------------------------ running
    def calibrate(self) -> str:
        """Start ``kinecal calibrate`` on the chosen files in a worker process."""
        s = self.app.session
        s.require_model()
        ds = s.data.get(self.data.value)
        if ds is None:
            raise InputError("no measurements to calibrate on: load a file first")
        if any(r.running for r in self.runs):
            raise InputError("a calibration is running: wait for it or stop it")
        val = s.data.get(self.validate.value)
        label = f"run {len(self.runs) + 1}"
        folder = s.workdir / f"run-{len(self.runs) + 1}"
        args = calibrate_args(s.model_spec, [ds.spec], [val.spec] if val is not None and
                              val is not ds else [], folder, self.method.value,
                              _links(s))
        run = Run(label, args, folder, on_change=self._run_changed)
        self.runs.append(run)
        self.start.disabled = True
        self.stop.disabled = False
        run.start()
        return f"{label} started: {run.command}"

    def stop_all(self) -> None:
        for run in self.runs:
            run.stop()

    def _run_changed(self, run: Run) -> None:
        if run.total:
            self.progress.animated = False
            self.progress.value = 100.0 * min(run.done / run.total, 1.0)
        else:
            self.progress.animated = run.running
            self.progress.value = 100.0 if not run.running else 50.0
        step = (f"{run.task}: {run.done}/{run.total}" if run.total else
                f"{run.task}: {run.done} it." if run.done else run.task)
        best = "" if run.best is None else f", best {run.best:.4g}"
        lines = [f"{run.label}: {run.status} ({run.seconds:.1f} s){' - ' if step else ''}"
                 f"{step}{best}", f"$ {run.command}", *run.warnings]
        if run.error:
            lines.append(run.error)
        self.status.content = _box("kc-run", "\n".join(lines), error=run.status == "failed")
        if run.running:
            return
        self.stop.disabled = True
        self.start.disabled = False
        if run.status == "done":
            try:
                self._finished(run)
            except InputError as exc:
                self.app.say(False, f"kinecal: error: {exc.one_line()}")
        elif run.status == "failed":
            self.app.say(False, run.error or f"{run.label} failed")

    def _finished(self, run: Run) -> None:
        out = self._outcome(run.label, run.folder / "result.json", run.folder, run)
        self.app.say(True, f"{run.label} done in {run.seconds:.1f} s: mean error "
                     f"{_mean(out.data, 'before')} -> {_mean(out.data, 'after')} "
                     f"{out.data.get('length_unit', '')}")

    def add_result_file(self, spec: str) -> str:
        """Open a result JSON written earlier (``kinecal calibrate --out``)."""
        out = self._outcome(Path(spec).name, Path(spec), None, None)
        return f"result {out.label}: mean error {_mean(out.data, 'after')}"

    def _outcome(self, label: str, path: Path, folder: Path | None, run: Run | None) -> Outcome:
        from kinecal._files import read_json
        from kinecal.io.result_values import parameters_from_data

        s = self.app.session
        data = read_json(path)
        if not isinstance(data, dict) or "parameters" not in data:
            raise InputError("expected a calibration result (kinecal calibrate --out)",
                             file=path)
        params = parameters_from_data(s.model, data, path)
        out = Outcome(label, folder, data, params, run)
        self.outcomes.append(out)
        if out.report is not None:
            self.app.front.publish(f"{label.replace(' ', '-')}/report.html", out.report)
        self.words.content = _box("kc-words", identifiability_words(data)) + self._links(out)
        self.app.see.set_result(params, label, data)
        self._lists()
        return out

    def _links(self, out: Outcome) -> str:
        if out.report is None:
            return ""
        url = f"/kinecal/files/{out.label.replace(' ', '-')}/report.html"
        return (f'<div style="padding:0 8px"><a class="kc-open" id="kc-report-link" '
                f'href="{url}">Open the report of {html.escape(out.label)}</a></div>')

    def _compare(self) -> None:
        by = {o.label: o for o in self.outcomes}
        a, b = by.get(self.left.value), by.get(self.right.value)
        if a is None or b is None:
            self.compare.content = ""
            return
        rows = [("method", a.data.get("method"), b.data.get("method"))]
        for part in ("calibration", "validation"):
            for when in ("before", "after"):
                rows.append((f"{part} {when} mean", _mean(a.data, when, part),
                             _mean(b.data, when, part)))
        rows += [("free parameters", len(a.data.get("free") or []),
                  len(b.data.get("free") or [])),
                 ("condition number", f"{a.data.get('condition_number', 0):.3g}",
                  f"{b.data.get('condition_number', 0):.3g}")]
        body = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(x))}</td>"
                       f"<td>{html.escape(str(y))}</td></tr>" for k, x, y in rows)
        table = (f'<table id="kc-compare" style="font-size:12px;margin:0 8px"><tr><th></th>'
                 f"<th>{html.escape(a.label)}</th><th>{html.escape(b.label)}</th></tr>"
                 f"{body}</table>")
        if a.report is not None and b.report is not None:
            ua = f"/kinecal/files/{a.label.replace(' ', '-')}/report.html"
            ub = f"/kinecal/files/{b.label.replace(' ', '-')}/report.html"
            table += (f'<div style="padding:4px 8px"><a class="kc-open" id="kc-pair-link" '
                      f'href="{ua}" data-pair="{ub}">Open both reports side by side</a></div>')
        self.compare.content = table


def _links(session) -> list[str]:
    extra = []
    if session.base_link:
        extra += ["--base-link", session.base_link]
    for tip in session.tip_links:
        extra += ["--tip-link", tip]
    return extra


def _mean(data: dict, when: str, part: str = "calibration") -> str:
    value = ((data.get(part) or {}).get(when) or {}).get("mean")
    return "-" if value is None else f"{value:.4g}"


def _box(ident: str, text: str, error: bool = False) -> str:
    color = "#8e1b12" if error else "inherit"
    return (f'<div id="{ident}" style="font-size:12px;padding:0 8px;white-space:pre-wrap;'
            f'color:{color}">{html.escape(text)}</div>')
