"""`CameraBlock`: camera pixels as one residual block of the stacked calibration
(`kinecal.calibration.blocks`, docs/measurement-kinds.md).

An observation is one image (station); its rows are the two pixel coordinates of every
corner found in it. The nuisance is the block's camera mount X, board pose and (optionally)
intrinsics, as increments on references set by `start` (the hand-eye closed form of
`kinecal.calibration.camera.start` on the nominal flange poses and the per-image board
poses). Residuals and Jacobians come from `kinecal.calibration.camera.block.PixelBlock`.
A camera block mixes with tracker points, ballbars, sockets and planes in one problem: the
stack shares the arm's columns and keeps each block's nuisance its own.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.base import BlockRows, ResidualBlock
from kinecal.calibration.camera.block import PixelBlock
from kinecal.calibration.camera.result import Stations
from kinecal.calibration.camera.start import closed_form_start
from kinecal.kinematics.serial.model import SerialModel

Array = NDArray[np.float64]

__all__ = ["CameraBlock"]


class CameraBlock(ResidualBlock):
    """Corner pixels of board images taken at known joints (module docstring).

    Parameters
    ----------
    stations : Stations
        Joints, detected corners and per-image board poses (for the start).
    K, dist
        Camera matrix and OpenCV distortion coefficients (start values when free).
    setup : {"eye-in-hand", "eye-to-hand"}
    n_int : int
        Free intrinsics: 0, 9 or 12.
    source : str
        Image folder or description (messages, reports).
    sigma : float, optional
        Stated corner noise per coordinate (px).
    method : str
        Hand-eye closed form of the start.
    robust_start : bool
        RANSAC start of the closed form (data that may hold wrong stations).
    """

    kind = "camera"
    unit = "px"
    obs_dof = 2
    noise_of = "each pixel coordinate of a detected corner"
    #: the board pose (eye-in-hand) or camera pose (eye-to-hand) takes up any rigid motion
    #: of the whole arm; the board's size fixes the scale
    blind_to = frozenset({"translation", "rotation"})
    #: residuals (px) at or below this are round-off: noise-free data, no noise to estimate
    round_off = 1e-7

    def __init__(self, stations: Stations, K: Array, dist: Array | None, setup: str,
                 n_int: int = 0, source: str = "images", sigma: float | None = None,
                 method: str = "park", robust_start: bool = False) -> None:
        super().__init__(source, stations.q, None, sigma)
        self.stations = stations
        self.K, self.dist, self.setup, self.n_int = K, dist, setup, n_int
        self.method, self.robust_start = method, robust_start
        self.pixels: PixelBlock | None = None
        self._recent: list[tuple[Any, bool, BlockRows]] = []
        #: stations the robust closed-form start judged inconsistent with the others
        self.start_outliers: list[int] = []
        counts = np.array([len(p) for p in stations.points], dtype=np.intp)
        self._obs = np.repeat(np.arange(len(counts), dtype=np.intp), 2 * counts)

    @property
    def n_obs(self) -> int:
        return len(self.stations.q)

    @property
    def obs_index(self) -> NDArray[np.intp]:
        return self._obs

    @property
    def nuisance_names(self) -> list[str]:
        from kinecal.calibration.camera.block import nuisance_names

        return nuisance_names(self.setup, self.n_int)

    def nuisance_scale(self, length: float) -> Array:
        s = np.ones(self.n_nuisance)
        s[[0, 1, 2, 6, 7, 8]] = 1.0 / length
        return s

    def observation_labels(self) -> list[str]:
        return list(self.stations.names)

    def start(self, model: SerialModel, params: Array) -> Array:
        """References X0, board pose from the closed form at `params`; zero increments."""
        if self.pixels is None:
            X0, Y0, seed = closed_form_start(model, self.q, self.stations.target2cam,
                                             self.setup, params, self.method,
                                             self.robust_start)
            self.start_outliers = [int(i) for i in (seed.outliers or [])]
            self.set_references(model, X0, Y0)
        return np.zeros(self.n_nuisance)

    def set_references(self, model: SerialModel, X0: Array, Y0: Array) -> None:
        """Set the references of X and the board pose (the increments' zero)."""
        st = self.stations
        self.pixels = PixelBlock(model, st.q, st.points, st.pixels, self.setup, self.K,
                                 self.dist, X0, Y0, self.n_int)

    def evaluate(self, model: SerialModel, params: Array, nuisance: Array,
                 columns: NDArray[np.intp] | None = None, jacobian: bool = False,
                 points: tuple[Array, Array | None] | None = None) -> BlockRows:
        """Pixel residuals (predicted minus detected, corner-major ``u, v``); `points` is
        not used: the camera needs the end frame's pose, not a tool point."""
        if self.pixels is None:
            self.start(model, params)
        cols = None if columns is None else np.asarray(columns, np.intp)
        # the stacked fit asks again where it was (a solver's last point, then the noise
        # estimate's and the analysis's): the rows of the last points are kept (read-only)
        key = (id(self.pixels), np.asarray(params, float).tobytes(),
               np.asarray(nuisance, float).tobytes(), None if cols is None else cols.tobytes())
        for k, jac, rows in self._recent:
            if k == key and (jac or not jacobian):
                return rows if jacobian or rows.arm is None else BlockRows(rows.r)
            if not jacobian and k[:3] == key[:3]:  # the residuals: the same for any columns
                return BlockRows(rows.r)
        uv, Ja, Jn = self.pixels.predict(params, nuisance, cols, jacobian)
        r = (uv - self.pixels.uv).ravel()
        if not jacobian:
            rows = BlockRows(r)
        else:
            m = r.size
            arm = Ja.reshape(m, -1) if Ja is not None else np.zeros((m, 0))
            rows = BlockRows(r, arm, Jn.reshape(m, -1))
        for a in (rows.r, rows.arm, rows.nuisance):
            if a is not None:
                a.flags.writeable = False
        self._recent = [(key, jacobian, rows), *self._recent[:2]]
        return rows

    def observation_errors(self, r: Array) -> Array:
        """RMS corner error per image (px, the norm of a corner's two coordinates)."""
        return self.pixels.station_rms(np.asarray(r).reshape(-1, 2))

    def nuisance_report(self, nuisance: Array, std: Array) -> list[dict[str, Any]]:
        X, Y, K, d = self.pixels.unpack(nuisance)
        std = np.asarray(std, float)
        xf = "cam2flange" if self.setup == "eye-in-hand" else "cam2base"
        bf = "target2base" if self.setup == "eye-in-hand" else "target2flange"
        out = [{"name": "X", "frame": xf, "matrix": X.tolist(),
                "std_rotation_deg": np.degrees(std[0:3]).tolist(),
                "std_translation": std[3:6].tolist()},
               {"name": "board", "frame": bf, "matrix": Y.tolist(),
                "std_rotation_deg": np.degrees(std[6:9]).tolist(),
                "std_translation": std[9:12].tolist()}]
        if self.n_int:
            out.append({"name": "intrinsics", "K": K.tolist(), "dist": d.tolist(),
                        "std": std[12:].tolist()})
        return out
