"""The See view: the robot at each measured pose (a slider steps through them), every
pose's residual as an arrow before and after calibration (drawn `gain` times its length,
coloured green to red by size on one scale for both), and what the calibration placed:
the tracker (the measurement frame), the robot's base, and the pivots, fixed points, planes,
cameras and boards of the result (`kinecal.ui.instruments`).

The arrows of all poses are sent once per data set or result; a slider move sends the
robot's cylinders and one marker, nothing more (``benchmarks/bench_ui.py`` times it).
"""

from __future__ import annotations

import functools
import html
import threading

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.ui.geometry import error_colors, residual_arrows
from kinecal.ui.scene import RobotFigure, model_scale

__all__ = ["SeeView"]

Array = NDArray[np.float64]


def _locked(method):
    """Run a drawing method under the view's lock (viser calls back on several threads)."""
    @functools.wraps(method)
    def run(self, *args, **kw):
        with self._lock:
            return method(self, *args, **kw)
    return run


class SeeView:
    """The See tab (module docstring); `app` is the `kinecal.ui.app.Workbench`."""

    def __init__(self, app, tab) -> None:
        self.app = app
        server = self.server = app.server
        self.robot = RobotFigure(server, "/robot", color=(150, 165, 185))
        from kinecal.ui.instruments import InstrumentsFigure

        self.instruments = InstrumentsFigure(server)
        self.placed: list = []
        self.params: Array | None = None  # calibrated parameters (None: nominal only)
        self.result_label = ""
        self.before: Array | None = None
        self.after: Array | None = None
        self._handles: dict[str, object] = {}
        self._shown: str | None = None
        self._marker: tuple | None = None  # (handle, radius) of the current pose's marker
        self._q_now: Array | None = None  # the joints shown (rad, the model's order)
        self._lock = threading.RLock()
        with tab:
            self.data = server.gui.add_dropdown("Data", ("(none)",), initial_value="(none)",
                                                hint="Measurement file whose poses are shown")
            self.pose = server.gui.add_slider("Pose", min=1, max=2, step=1, initial_value=1,
                                              disabled=True, hint="Step through the poses")
            self.show_before = server.gui.add_checkbox("Errors before", True)
            self.show_after = server.gui.add_checkbox("Errors after", True)
            self.gain = server.gui.add_slider("Arrow scale (log10)", min=0.0, max=4.0,
                                              step=0.1, initial_value=2.0)
            self.info = server.gui.add_html(_info_html("No poses yet: load a model and its "
                                                       "measurements."))
            self.legend = server.gui.add_html("")
        self.data.on_update(lambda _: self.refresh())
        self.pose.on_update(lambda _: self._stepped())
        for box in (self.show_before, self.show_after):
            box.on_update(lambda _: self._visibility())
        self.gain.on_update(lambda _: self._draw_arrows())
        server.scene.add_frame("/tracker", axes_length=0.15, axes_radius=0.004)
        server.scene.add_label("/tracker/label", "tracker (measurement frame)")

    # ------------------------------------------------------------------ state
    @_locked
    def set_result(self, params: Array | None, label: str = "",
                   data: dict | None = None) -> None:
        """Show the arm with calibrated `params` (None: nominal) and the errors after;
        what the result `data` (its JSON) placed besides the arm (`kinecal.ui.instruments`)."""
        from kinecal.ui.instruments import placed_of

        self.params = None if params is None else np.asarray(params, dtype=float)
        self.result_label = label
        self.placed = [] if data is None else placed_of(data)
        self.refresh()
        model = self.app.session.model
        if model is not None and self.robot.skeleton is not None:
            self.instruments.show(self.placed, model_scale(model), self.robot.skeleton.size)
            if self._q_now is not None:
                self._place_carried(self._q_now)
        else:
            self.instruments.clear()

    def data_names(self) -> list[str]:
        s = self.app.session
        return [n for n, d in s.data.items() if d.meas is not None]

    @_locked
    def refresh(self) -> None:
        """Redraw for the chosen data set (a model or data change, a new result)."""
        s = self.app.session
        names = self.data_names()
        options = tuple(names) or ("(none)",)
        if tuple(self.data.options) != options:
            self.data.options = options
        if self.data.value not in options:
            self.data.value = options[-1]
        ds = s.data.get(self.data.value)
        if s.model is None:
            self.robot.remove()
            self._clear()
            return
        if ds is None or ds.meas is None:
            self._clear()
            q = np.zeros((1, s.model.n_joints))
            self.robot.set_poses(s.model, q, self.params, s.urdf())
            self.robot.show(0)
            self._place_carried(q[0])
            if self._shown != s.model_spec:
                self._shown = s.model_spec
                self._frame(self.robot.skeleton.points[0])
            self.pose.disabled = True
            self.info.content = _info_html(f"{html.escape(s.model.name)} at zero: load "
                                           "measurements to see its poses.")
            return
        meas = ds.meas
        self.robot.set_poses(s.model, meas.q, self.params, s.urdf())
        nominal = s.model.positions(meas.q, None, meas.marker)
        self.before = np.linalg.norm(meas.xyz - nominal, axis=1)
        self.after = None
        calibrated = None
        if self.params is not None:
            calibrated = s.model.positions(meas.q, self.params, meas.marker)
            self.after = np.linalg.norm(meas.xyz - calibrated, axis=1)
        self._nominal, self._calibrated = nominal, calibrated
        k = model_scale(s.model)
        self.server.scene.add_point_cloud("/poses/measured", (meas.xyz * k).astype(np.float32),
                                          colors=(60, 60, 60), point_size=0.004,
                                          point_shape="circle")
        n = len(meas.q)
        self.pose.disabled = n < 2
        self.pose.max = max(n, 2)
        if ds.name != self._shown:  # a new data set: arrows scaled to be seen, camera
            self._shown = ds.name
            top = float(self.before.max(initial=0.0)) * k or 1.0
            self.gain.value = round(float(np.clip(np.log10(0.25 * self.robot.skeleton.size
                                                           / top), 0.0, 4.0)), 1)
            self._frame(np.vstack([self.robot.skeleton.points[0], meas.xyz * k]))
        self._draw_arrows()
        self.show_pose(min(int(self.pose.value), n) - 1)

    def _stepped(self) -> None:
        self.app.plan.show_ghost(False)  # the See view's robot alone
        self.show_pose(int(self.pose.value) - 1)

    def _frame(self, points: Array) -> None:
        """Point the camera of new pages (and of those open) at `points` (scene units)."""
        lo, hi = points.min(axis=0), points.max(axis=0)
        center = (lo + hi) / 2
        size = float(max(np.ptp(points, axis=0).max(), 0.2))
        eye = center + size * np.array([0.75, -1.1, 0.55])
        self.server.initial_camera.position = tuple(eye)
        self.server.initial_camera.look_at = tuple(center)
        for client in self.server.get_clients().values():
            client.camera.position = tuple(eye)
            client.camera.look_at = tuple(center)

    def _clear(self) -> None:
        for key in ("before", "after"):
            for h in self._handles.pop(key, ()):
                h.remove()
        self.server.scene.remove_by_name("/poses")
        if self._marker is not None:
            self._marker[0].remove()
            self._marker = None
        self.before = self.after = None
        self.legend.content = ""

    # ------------------------------------------------------------------ drawing
    @_locked
    def _draw_arrows(self) -> None:
        s = self.app.session
        ds = s.data.get(self.data.value)
        if ds is None or ds.meas is None or self.before is None:
            return
        k = model_scale(s.model)
        top = float(self.before.max(initial=0.0)) or 1.0
        gain = 10.0 ** float(self.gain.value)
        size = self.robot.skeleton.size if self.robot.skeleton is not None else 1.0
        radius = 0.008 * size
        for key, pred, err in (("before", self._nominal, self.before),
                               ("after", self._calibrated, self.after)):
            for h in self._handles.pop(key, ()):
                h.remove()
            if pred is None:
                continue
            # lines and a dot at the head: software-rendered WebGL (no GPU) draws 2000
            # of these at 50 frames a second, 2000 meshed arrows at one
            arrows = residual_arrows(pred * k, ds.meas.xyz * k, gain).astype(np.float32)
            colors = error_colors(err, top)
            self._handles[key] = (
                self.server.scene.add_line_segments(
                    f"/poses/{key}/shafts", arrows, np.repeat(colors[:, None], 2, axis=1),
                    thickness=2.0, thickness_units="screen"),
                self.server.scene.add_point_cloud(
                    f"/poses/{key}/heads", arrows[:, 1], colors=colors, point_size=radius,
                    point_shape="circle"))
        self._visibility()
        unit = s.model.length_unit
        after = ("" if self.after is None else
                 f"; after ({html.escape(self.result_label)}): mean {self.after.mean():.4g}, "
                 f"max {self.after.max():.4g} {unit}")
        self.legend.content = (
            f'<div id="kc-legend" style="font-size:12px;padding:0 8px">Arrows: each pose\'s '
            f"error, drawn {gain:.3g} times its length, from the model's point to the "
            f"measured one; colour by size: <b style='color:#28aa50'>0</b> to "
            f"<b style='color:#dc2828'>{top:.3g} {unit}</b>. Before: mean "
            f"{self.before.mean():.4g}, max {top:.4g} {unit}{after}.</div>")

    def _visibility(self) -> None:
        for key, box in (("before", self.show_before), ("after", self.show_after)):
            for h in self._handles.get(key, ()):
                h.visible = bool(box.value)

    @_locked
    def show_pose(self, index: int) -> None:
        """Draw the robot at pose `index` (0-based) and mark its measured point."""
        s = self.app.session
        ds = s.data.get(self.data.value)
        if ds is None or ds.meas is None or self.robot.skeleton is None:
            return
        n = len(ds.meas.q)
        index = int(np.clip(index, 0, n - 1))
        self.robot.show(index)
        self._place_carried(ds.meas.q[index])
        k = model_scale(s.model)
        p = ds.meas.xyz[index] * k
        size = self.robot.skeleton.size
        radius = 0.012 * size
        if self._marker is None or self._marker[1] != radius:  # made once per data set
            if self._marker is not None:
                self._marker[0].remove()
            self._marker = (self.server.scene.add_icosphere(
                "/marker", radius=radius, color=(30, 90, 200), position=tuple(p)), radius)
        else:  # a move sends the new position only
            self._marker[0].position = tuple(float(v) for v in p)
        unit = s.model.length_unit
        q = ds.meas.q[index] / s.model.joint_scale()
        after = "" if self.after is None else f", after {self.after[index]:.4g} {unit}"
        self.info.content = _info_html(
            f"pose {index + 1} of {n} ({html.escape(ds.name)}): error before "
            f"{self.before[index]:.4g} {unit}{after}<br>joints: "
            + ", ".join(f"{v:.4g}" for v in q))


    def _place_carried(self, q: Array) -> None:
        """Move what a link carries (cameras, boards) to the arm's pose at joints `q`."""
        self._q_now = np.asarray(q, dtype=float)
        model = self.app.session.model
        if not self.instruments.carried or model is None:
            return
        self.instruments.move(lambda link: carrier_frame(model, self._q_now, link,
                                                         self.params), model_scale(model))


def carrier_frame(model, q: Array, link: str, params: Array | None = None) -> Array | None:
    """The frame ``(4, 4)`` of `link` (model units, base frame) at joints `q` with `params`:
    ``flange``, a serial model's end frame (its tool frame when it has one, as the camera
    block places a camera on the flange), or a link of a robot system; None if unknown."""
    q = np.asarray(q, dtype=float)[None]
    if hasattr(model, "link_poses"):  # a robot system: any of its links
        try:
            return model.link_poses(q, link, params)[0]
        except (KeyError, ValueError, InputError):
            return None
    if link in ("flange", "tool"):
        return model.fk(q, params)[0]
    return None


def _info_html(text: str) -> str:
    return f'<div id="kc-pose" style="font-size:12px;padding:0 8px">{text}</div>'
