"""The Plan view: choose calibration poses by hand (joint sliders within the joint limits;
add, remove) or by ``kinecal select-poses`` (in a worker process), see at once what they
identify and how well (`kinecal.ui.planning`), whether a pose collides with itself (the
URDF's collision meshes, `kinecal.ui.collision`), and save the plan as CSV (the columns
``select-poses`` writes) and as a robot program (the writers of ``select-poses
--program``, `kinecal.io.programs.write_model_program`).
"""

from __future__ import annotations

import html

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.ui.runs import Run
from kinecal.ui.scene import RobotFigure, model_scale

__all__ = ["PROGRAMS", "PlanView"]

Array = NDArray[np.float64]

#: robot program languages offered, by the suffix that names them
PROGRAMS = {"URScript (.script)": ".script", "ABB RAPID (.mod)": ".mod",
            "KUKA KRL (.src)": ".src", "ROS 2 JointTrajectory (.yaml)": ".yaml"}


class PlanView:
    """The Plan tab (module docstring)."""

    def __init__(self, app, tab) -> None:
        self.app = app
        self.server = server = app.server
        self.tab = tab
        self.ghost = RobotFigure(server, "/plan/ghost", color=(235, 140, 40), opacity=0.55)
        self.sliders: list = []
        self.collider = None
        self._model = None
        self._selecting: Run | None = None
        self._touched = False  # the ghost shows once a joint slider has moved
        self._figures: tuple | None = None  # (plan key, lines) of the last figures
        gui = server.gui
        with tab:
            self.joints = gui.add_folder("Joints")
            self.add = gui.add_button("Add this pose", color="blue", disabled=True)
            self.remove = gui.add_button("Remove pose", disabled=True)
            self.step = gui.add_slider("Plan pose", min=1, max=2, step=1, initial_value=1,
                                       disabled=True)
            self.clear = gui.add_button("Clear the plan", disabled=True)
            self.noise = gui.add_number("Instrument noise (1 sigma)", 0.01, min=1e-6,
                                        step=0.001, hint="Per coordinate, the model's "
                                        "length unit")
            with gui.add_folder("Select poses (D-optimal)"):
                self.count = gui.add_number("Poses", 30, min=1, max=10000, step=1)
                self.candidates = gui.add_number("Candidates", 2000, min=10, max=200000,
                                                 step=100)
                self.select = gui.add_button("Select poses", disabled=True)
            self.figures = gui.add_html("")
            with gui.add_folder("Save"):
                self.language = gui.add_dropdown("Program", tuple(PROGRAMS))
                self.save_csv = gui.add_button("Save plan CSV", disabled=True)
                self.save_program = gui.add_button("Save robot program", disabled=True)
                self.saved = gui.add_html("")
        self.add.on_click(lambda _: self.app._guarded(self.add_pose))
        self.remove.on_click(lambda _: self.app._guarded(self.remove_pose))
        self.clear.on_click(lambda _: self.app._guarded(self.clear_plan))
        self.step.on_update(lambda _: self._goto(int(self.step.value) - 1))
        self.noise.on_update(lambda _: self.update_figures())
        self.select.on_click(lambda _: self.app._guarded(self.select_poses))
        self.save_csv.on_click(lambda _: self.app._guarded(self.write_csv))
        self.save_program.on_click(lambda _: self.app._guarded(self.write_program))

    # ------------------------------------------------------------------ model
    def refresh(self) -> None:
        s = self.app.session
        if s.model is not self._model:
            self._model = s.model
            self._build_sliders()
        enabled = s.model is not None and not s.is_system
        for b in (self.add, self.select):
            b.disabled = not enabled
        self._plan_changed()

    def _build_sliders(self) -> None:
        for sl in self.sliders:
            sl.remove()
        self.sliders = []
        self.ghost.remove()
        self.collider = None
        self._touched = False
        model = self.app.session.model
        if model is None or self.app.session.is_system:
            return
        lim = model.joint_limits / model.joint_scale()[:, None]
        names = _joint_labels(model)
        with self.joints:
            for j in range(model.n_joints):
                lo, hi = float(lim[j, 0]), float(lim[j, 1])
                step = 0.1 if model.is_prismatic()[j] or hi - lo > 20 else 0.001
                unit = model.length_unit if model.is_prismatic()[j] else model.angle_unit
                sl = self.server.gui.add_slider(f"{names[j]} [{unit}]", min=lo, max=hi,
                                                step=step,
                                                initial_value=float(np.clip(0.0, lo, hi)))
                sl.on_update(lambda _: self._moved())
                self.sliders.append(sl)
        urdf = self.app.session.urdf()
        if urdf is not None:
            try:
                from kinecal.ui.collision import SelfCollision

                self.collider = SelfCollision(urdf)
            except (ImportError, ValueError):
                self.collider = None
        self._moved()

    def q_now(self) -> Array:
        """The joint sliders' pose (rad; prismatic: length unit)."""
        model = self.app.session.model
        return np.array([sl.value for sl in self.sliders], dtype=float) * model.joint_scale()

    def _moved(self) -> None:
        model = self.app.session.model
        if model is None or not self.sliders:
            return
        q = self.q_now()[None]
        self.ghost.set_poses(model, q, None, None)
        self.ghost.show(0)
        self.show_ghost(self._touched)
        self._touched = True
        self.update_figures()

    def show_ghost(self, visible: bool) -> None:
        """Show or hide the pose being planned (hidden while the See view steps)."""
        self.ghost.set_visible(visible)

    def _collisions(self, q: Array) -> list[tuple[str, str]]:
        if self.collider is None:
            return []
        names = list(self.collider.urdf.actuated_joint_names)
        cfg = np.zeros(len(names))
        for j, name in enumerate(_joint_labels(self.app.session.model)):
            if name in names:
                cfg[names.index(name)] = q[j]
        return self.collider.collisions(cfg)

    # ------------------------------------------------------------------ the plan
    @property
    def plan(self) -> Array:
        s = self.app.session
        n = 0 if s.model is None else s.model.n_joints
        return s.plan if s.plan is not None else np.zeros((0, n))

    def _set_plan(self, q: Array | None) -> None:
        with self.app.session.lock:
            self.app.session.plan = q
        self._plan_changed()

    def add_pose(self) -> str:
        model = self.app.session.require_model()
        q = self.q_now()
        lo, hi = model.joint_limits[:, 0], model.joint_limits[:, 1]
        if ((q < lo) | (q > hi)).any():
            raise InputError("the pose is outside the joint limits")
        hits = self._collisions(q)
        if hits:
            raise InputError("the pose collides with itself: " + ", ".join(
                f"{a} with {b}" for a, b in hits))
        self._set_plan(np.vstack([self.plan, q[None]]))
        return f"pose {len(self.plan)} added to the plan"

    def remove_pose(self) -> str:
        plan = self.plan
        if not len(plan):
            raise InputError("the plan has no poses")
        k = int(np.clip(int(self.step.value) - 1, 0, len(plan) - 1))
        self._set_plan(np.delete(plan, k, axis=0))
        return f"pose {k + 1} removed from the plan"

    def clear_plan(self) -> str:
        self._set_plan(None)
        return "plan cleared"

    def _goto(self, k: int) -> None:
        plan = self.plan
        if not len(plan):
            return
        q = plan[int(np.clip(k, 0, len(plan) - 1))] / self.app.session.model.joint_scale()
        for sl, v in zip(self.sliders, q, strict=True):
            sl.value = float(np.clip(v, sl.min, sl.max))

    def _plan_changed(self) -> None:
        plan, model = self.plan, self.app.session.model
        n = len(plan)
        for b in (self.remove, self.clear, self.save_csv, self.save_program):
            b.disabled = n == 0
        self.step.disabled = n < 2
        self.step.max = max(n, 2)
        if n and model is not None:
            pts = model.positions(plan) * model_scale(model)
            self.server.scene.add_point_cloud("/plan/points", pts.astype(np.float32),
                                              colors=(235, 140, 40), point_size=0.012,
                                              point_shape="diamond")
        else:
            self.server.scene.remove_by_name("/plan/points")
        self.update_figures()

    def update_figures(self) -> None:
        """Recompute and show the plan's figures (module docstring)."""
        s = self.app.session
        if s.model is None or s.is_system:
            self.figures.content = _html("kc-plan", "Plan views of robot systems: use "
                                         "kinecal select-poses SYSTEM (docs/systems.md).")
            return
        plan = self.plan
        lines = []
        q = self.q_now() if self.sliders else None
        if q is not None:
            hits = self._collisions(q)
            lines.append("this pose: " + ("collides: " + ", ".join(f"{a} with {b}" for a, b
                                                                    in hits)
                                          if hits else "no self-collision" if self.collider
                                          else "within the joint limits (no collision "
                                          "meshes: a URDF gives them)"))
        if not len(plan):
            lines.append("plan: no poses yet (Add this pose, or Select poses)")
            self.figures.content = _html("kc-plan", "\n".join(lines))
            return
        lines += self._plan_lines(s.model, plan, float(self.noise.value))
        self.figures.content = _html("kc-plan", "\n".join(lines))

    def _plan_lines(self, model, plan: Array, noise: float) -> list[str]:
        """The plan's figures in words, recomputed only when the plan or the noise changed
        (a joint slider's move changes neither)."""
        from kinecal.ui.planning import plan_figures

        key = (id(model), plan.tobytes(), noise)
        if self._figures is not None and self._figures[0] == key:
            return self._figures[1]
        f = plan_figures(model, plan, noise)
        unit = model.length_unit
        lines = [f"plan: {f.n_poses} poses; rank {f.rank} of {f.n_params}; condition "
                  f"number {f.condition_number:.4g}",
                  f"predicted position uncertainty after calibration: {f.position_sigma:.3g} "
                  f"{unit} (1 sigma, rms over the poses)"]
        if f.std:
            worst = sorted(f.std.items(), key=lambda kv: -kv[1] * (1000.0 if kv[0] in
                                                                   f.angles else 1.0))[:5]
            lines.append("least certain: " + ", ".join(
                f"{n} {v * 180 / np.pi:.2g} deg" if n in f.angles else f"{n} {v:.2g} {unit}"
                for n, v in worst))
        if f.unidentifiable:
            lines.append("held at nominal: " + ", ".join(f.unidentifiable))
        self._figures = (key, lines)
        return lines

    # ------------------------------------------------------------------ select, save
    def select_poses(self) -> str:
        """``kinecal select-poses`` on the model, in a worker process; loads its plan."""
        s = self.app.session
        s.require_model()
        if self._selecting is not None and self._selecting.running:
            raise InputError("a pose selection is running")
        folder = s.workdir / "plans"
        out = folder / "selected.csv"
        args = ["select-poses", s.model_spec, "--count", str(int(self.count.value)),
                "--candidates", str(int(self.candidates.value)), "--out", str(out)]
        args += _chain_options(s)
        run = Run("select-poses", args, folder, on_change=self._selected)
        self._selecting = run.start()
        return f"selecting poses: {run.command}"

    def _selected(self, run: Run) -> None:
        if run.running:
            self.saved.content = _html("kc-saved", f"selecting poses... {run.seconds:.1f} s")
            return
        if run.status != "done":
            self.app.say(False, run.error or "select-poses failed")
            return
        q = self.app.session.read_plan(str(run.folder / "selected.csv"))
        self._plan_changed()
        self.app.say(True, f"select-poses chose {len(q)} poses: {run.command}")

    def _target(self, suffix: str) -> tuple:
        s = self.app.session
        folder = s.workdir / "plans"
        folder.mkdir(parents=True, exist_ok=True)
        return s, folder / f"plan{suffix}"

    def write_csv(self) -> str:
        from kinecal.io.csvtable import write_table

        s, path = self._target(".csv")
        q = self.plan / s.model.joint_scale()
        write_table(path, {f"q{i + 1}": q[:, i] for i in range(q.shape[1])})
        return self._saved(path)

    def write_program(self) -> str:
        """The plan as the robot program ``select-poses --program`` writes
        (`kinecal.io.programs.write_model_program`)."""
        from kinecal.io.programs import write_model_program

        s, path = self._target(PROGRAMS[self.language.value])
        write_model_program(path, s.model, self.plan,
                            comment=f"kinecal workbench plan for {s.model.name}")
        return self._saved(path)

    def _saved(self, path) -> str:
        url = self.app.front.publish(f"plans/{path.name}", path)
        self.saved.content = (f'<div id="kc-saved" style="font-size:12px;padding:0 8px">wrote '
                              f'<a href="{url}" download="{path.name}">{html.escape(str(path))}'
                              "</a></div>")
        return f"wrote {len(self.plan)} poses to {path}"


def _joint_labels(model) -> list[str]:
    names = [j.get("name") for j in getattr(model, "joints", ()) if "frame" not in j]
    if len(names) == model.n_joints and all(names):
        return names
    return [f"q{i + 1}" for i in range(model.n_joints)]


def _chain_options(session) -> list[str]:
    extra = []
    if session.base_link:
        extra += ["--base-link", session.base_link]
    for tip in session.tip_links:
        extra += ["--tip-link", tip]
    return extra


def _html(ident: str, text: str) -> str:
    return (f'<div id="{ident}" style="font-size:12px;padding:0 8px;white-space:pre-wrap">'
            f"{html.escape(text)}</div>")
