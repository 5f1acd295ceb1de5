"""`RigBlock`: the pixels of a camera rig as one residual block of the stacked calibration
(`kinecal.calibration.blocks`).

An observation is one image; its rows are the two pixel coordinates of every corner of
every board found in it. The nuisance is the rig's: every camera's mount (``cam2link``),
every board's mount (``board2link``) and, optionally, each camera's intrinsics, as
increments on references set by `start` (`kinecal.calibration.camera.rig_start`: PnP per
image, a closed form per camera-board pair). The model's parameters (an arm's or a robot
system's) are the stack's columns, reached through the mounting links' poses
(`kinecal.calibration.camera.rig_frames`). Residuals and Jacobians come from
`kinecal.calibration.camera.rig_pixels.RigPixels`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, ResidualBlock
from kinecal.calibration.camera.rig_frames import LinkFrames
from kinecal.calibration.camera.rig_pixels import Mount, RigPixels, RigViews, mount_names
from kinecal.calibration.camera.rig_start import rig_start
from kinecal.kinematics.tree.system import is_system

Array = NDArray[np.float64]

__all__ = ["RigBlock"]


class RigBlock(ResidualBlock):
    """Corner pixels of a rig's images taken at known joints (module docstring).

    Parameters
    ----------
    views : RigViews
        Images, their cameras, joints, corners and (for the start) PnP board poses.
    cameras, boards : sequence of Mount
        The rig's cameras and boards with their (resolved) links.
    K, dist : sequence
        Per camera: camera matrix and distortion (start values when free).
    n_int : sequence of int
        Free intrinsics per camera: 0, 9 or 12.
    source : str
        Image folder or description.
    sigma : float, optional
        Stated corner noise per coordinate (px).
    method : str
        Hand-eye closed form of the start.
    frames : LinkFrames or FixedFrames, optional
        The links' poses per image (default: the model's, at the start).
    """

    kind = "rig"
    unit = "px"
    obs_dof = 2
    noise_of = "each pixel coordinate of a detected corner"
    #: a rigid motion of the world frame with every mount on it changes no pixel; the
    #: boards' sizes fix the scale
    blind_to = frozenset({"translation", "rotation"})
    #: residuals (px) at or below this are round-off (noise-free data: no noise to estimate,
    #: no outlier): the bundle stops within ~1e-6 px of exact corners, a thousandth of the
    #: best detector's precision
    round_off = 1e-5

    def __init__(self, views: RigViews, cameras: Sequence[Mount], boards: Sequence[Mount],
                 K: Sequence[Array], dist: Sequence[Array | None], n_int: Sequence[int],
                 source: str = "images", sigma: float | None = None, method: str = "park",
                 frames=None) -> None:
        super().__init__(source, views.q, None, sigma)
        self.views = views
        self.cameras, self.boards = list(cameras), list(boards)
        self.K, self.dist, self.n_int = list(K), list(dist), [int(k) for k in n_int]
        self.method = method
        self.frames = frames
        self.pixels: RigPixels | None = None
        counts = np.array([len(p) for p in views.points], dtype=np.intp)
        self._obs = np.repeat(np.arange(len(counts), dtype=np.intp), 2 * counts)

    @property
    def n_obs(self) -> int:
        return len(self.views.q)

    @property
    def obs_index(self) -> NDArray[np.intp]:
        return self._obs

    @property
    def nuisance_names(self) -> list[str]:
        return mount_names(self.cameras, self.boards, self.n_int)

    def nuisance_scale(self, length: float) -> Array:
        s = np.ones(self.n_nuisance)
        for k in range(len(self.cameras) + len(self.boards)):
            s[6 * k:6 * k + 3] = 1.0 / length
        return s

    def observation_labels(self) -> list[str]:
        return list(self.views.names)

    def configurations(self) -> tuple[Array, NDArray[np.intp] | None]:
        """The images' joints; on a robot system, at every tip (the blind motions move
        every chain)."""
        model = getattr(self.frames, "model", None)
        if model is not None and is_system(model) and len(model.tips) > 1:
            n = len(self.q)
            return (np.tile(self.q, (len(model.tips), 1)),
                    np.repeat(np.arange(len(model.tips), dtype=np.intp), n))
        return self.q, None

    def _frames(self, model):
        if self.frames is None or (self.frames.model is not None and
                                   self.frames.model is not model):
            self.frames = LinkFrames(model, self.views.q,
                                     [m.link for m in self.cameras + self.boards])
        return self.frames

    def start(self, model, params: Array) -> Array:
        """References of every mount from the closed forms at `params`; zero increments."""
        frames = self._frames(model)
        if self.pixels is None:
            X0, Y0 = rig_start(frames, self.views, self.cameras, self.boards, params,
                               self.method)
            self.set_references(X0, Y0)
        return np.zeros(self.n_nuisance)

    def set_references(self, X0: Sequence[Array], Y0: Sequence[Array], K=None,
                       dist=None) -> None:
        """Set the mounts' references (the increments' zero) and optionally the cameras'
        intrinsics."""
        self.pixels = RigPixels(self.frames, self.views, self.cameras, self.boards,
                                self.K if K is None else K, self.dist if dist is None else dist,
                                X0, Y0, self.n_int)

    def evaluate(self, model, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        """Pixel residuals (predicted minus detected, corner-major ``u, v``)."""
        if self.pixels is None:
            self.start(model, params)
        self._frames(model)
        cols = None if columns is None else np.asarray(columns, np.intp)
        uv, J = self.pixels.predict(params, nuisance, cols, jacobian)
        r = (uv - self.pixels.uv).ravel()
        if not jacobian:
            return BlockRows(r)
        m = r.size
        return BlockRows(r, J.arm.reshape(m, -1),
                         J.dense_nuisance(self.pixels.n_nuisance))

    def normal_parts(self, model, params: Array, nuisance: Array,
                     columns: NDArray[np.intp], weights: Array) -> tuple:
        """The block-sparse normal equations of the pixels
        (`kinecal.calibration.camera.rig_jacobian.RigJacobian.normal`)."""
        if self.pixels is None:
            self.start(model, params)
        self._frames(model)
        uv, J = self.pixels.predict(params, nuisance, np.asarray(columns, np.intp), True)
        r = (uv - self.pixels.uv).ravel() * weights
        return (r, *J.normal(weights, r, self.pixels.n_nuisance))

    def observation_errors(self, r: Array) -> Array:
        """RMS corner error per image (px)."""
        return self.pixels.image_rms(np.asarray(r).reshape(-1, 2))

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict[str, Any]]:
        X, Y, K, d = self.pixels.unpack(nuisance)
        std = np.asarray(std, float)
        sl = self.pixels.slices
        out = []
        for what, mounts, poses in (("camera", self.cameras, X), ("board", self.boards, Y)):
            for m, T, s in zip(mounts, poses, sl[what], strict=True):
                out.append({"name": f"{what} {m.name}", "link": m.link,
                            "frame": f"{what}2{m.link}", "matrix": T.tolist(),
                            "std_rotation_deg": np.degrees(std[s][:3]).tolist(),
                            "std_translation": std[s][3:].tolist()})
        for c, k, s, Kc, dc in zip(self.cameras, self.n_int, sl["intrinsics"], K, d,
                                   strict=True):
            if k:
                out.append({"name": f"{c.name} intrinsics", "K": Kc.tolist(),
                            "dist": dc.tolist(), "std": std[s].tolist()})
        return out
