"""Hand-eye calibration of several cameras from images and robot poses: X per camera, the
board pose, the camera-to-camera extrinsics, in one bundle adjustment on the pixels.

The robot's flange poses are given (``handeye-images``'s ROBOT_POSES with a ``camera``
column): no model parameter moves them, so the rig's pixel block
(`kinecal.calibration.camera.rig_block.RigBlock`) runs on `FixedFrames` and only its own
unknowns are fitted: every camera's mount (``cam2flange`` eye-in-hand, ``cam2base``
eye-to-hand), the board's pose (``target2base`` / ``target2flange``) and the estimated
intrinsics. The start is the rig's (a closed form per camera, `kinecal.calibration.camera.
rig_start`); the normal equations are block-sparse (each image reaches its camera and the
board). The covariance of the mounts is the inverse normal matrix scaled by the residual's
variance, and propagates to every pair of cameras (camera B in camera A, with its sigma).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.blocks.stack import fit_nuisance
from kinecal.calibration.camera.rig_block import RigBlock
from kinecal.calibration.camera.rig_frames import FLANGE, WORLD, FixedFrames
from kinecal.calibration.camera.rig_pixels import Mount, RigViews
from kinecal.calibration.camera.rig_result import mount_entries, pixel_stats
from kinecal.calibration.camera.rig_solve import _relative
from kinecal.diagnostics import Diagnostic
from kinecal.errors import InputError

Array = NDArray[np.float64]

__all__ = ["RigHandEyeResult", "calibrate_rig_handeye"]


@dataclass
class RigHandEyeResult:
    """Outcome of `calibrate_rig_handeye` (attributes as `RigResult`'s mounts)."""

    setup: str
    cameras: list[Mount]
    boards: list[Mount]
    board_specs: list[str]
    camera_poses: list[Array]
    board_poses: list[Array]
    camera_sigma: list[Array]
    board_sigma: list[Array]
    K: list[Array]
    dist: list[Array]
    intrinsics_free: list[bool]
    intrinsics_sigma: list[Array | None]
    pairs: dict
    names: list[str]
    camera_of: Array
    before_px: Array
    after_px: Array
    sigma_px: float
    iterations: int = 0
    seconds: float = 0.0
    warnings: list[Diagnostic] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON of ``kinecal handeye-images --camera NAME ...``."""
        from kinecal import __version__
        from kinecal.calibration.serial.result import _finite

        cams, boards, pairs = mount_entries(self)
        names = [c.name for c in self.cameras]
        out = {"kinecal": __version__, "kind": "handeye-rig", "setup": self.setup,
               "method": "lm", "cameras": cams, "boards": boards,
               "camera_to_camera": pairs,
               "X_frame": "cam2flange" if self.setup == "eye-in-hand" else "cam2base",
               "board_frame": "target2base" if self.setup == "eye-in-hand"
               else "target2flange",
               "calibration": {"start": pixel_stats(self.before_px),
                               "after": pixel_stats(self.after_px)},
               "sigma_px": self.sigma_px,
               "images": [{"image": n, "camera": names[int(c)], "rms_px": float(a)}
                          for n, c, a in zip(self.names, self.camera_of, self.after_px,
                                             strict=True)],
               "iterations": self.iterations, "seconds": self.seconds}
        out.update(self.extra)
        out["warnings"] = [d.to_dict() for d in self.warnings]
        return _finite(out)

    def summary(self) -> str:
        """Plain-text summary: every camera's X with its sigma, the board, the pairs."""
        frame = "cam2flange" if self.setup == "eye-in-hand" else "cam2base"
        lines = [f"{len(self.names)} images of {len(self.cameras)} cameras, {self.setup}; "
                 f"reprojection RMS {np.sqrt(np.mean(self.after_px ** 2)):.3f} px (corner "
                 f"sigma {self.sigma_px:.3f} px)"]
        for m, T, s in zip(self.cameras, self.camera_poses, self.camera_sigma, strict=True):
            t = ", ".join(f"{v:.3f}" for v in T[:3, 3])
            lines.append(f"  X {m.name} ({frame}): t = ({t}) +- {np.linalg.norm(s[3:]):.3f}, "
                         f"rotation +- {np.degrees(np.linalg.norm(s[:3])):.4f} deg")
        names = [c.name for c in self.cameras]
        for (a, b), (T, s) in self.pairs.items():
            lines.append(f"  camera {names[b]} in camera {names[a]}: baseline "
                         f"{np.linalg.norm(T[:3, 3]):.3f} +- {np.linalg.norm(s[3:]):.3f}")
        if self.warnings:
            lines += ["", f"warnings ({len(self.warnings)}):"]
            lines += [f"  [{d.code}] {d.message}" for d in self.warnings]
        return "\n".join(lines)


def calibrate_rig_handeye(views: RigViews, flange2base: Array, camera_names: Sequence[str],
                          K: Sequence[Array], dist: Sequence[Array | None], *,
                          setup: str = "eye-in-hand",
                          refine_intrinsics: Sequence[bool] | None = None,
                          rational: bool = False, board_spec: str = "",
                          method: str = "park") -> RigHandEyeResult:
    """Hand-eye calibration of several cameras (module docstring).

    Parameters
    ----------
    views : RigViews
        The used images (one board, index 0), their cameras and PnP board poses; its
        joints are not used.
    flange2base : ndarray, shape (n, 4, 4)
        The robot's flange pose of every image of `views`.
    camera_names : sequence of str
    K, dist : sequence
        Per camera.
    setup : {"eye-in-hand", "eye-to-hand"}
    refine_intrinsics : sequence of bool, optional
        Per camera (default: none).
    """
    if setup not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {setup!r}; expected eye-in-hand or eye-to-hand",
                         option="--setup")
    t0 = time.perf_counter()
    with diagnostics.collect(python_warnings=True) as found:
        in_hand = setup == "eye-in-hand"
        cams = [Mount(n, FLANGE if in_hand else WORLD) for n in camera_names]
        board = [Mount("board", WORLD if in_hand else FLANGE)]
        flags = list(refine_intrinsics or [False] * len(cams))
        n_int = [(12 if rational else 9) if f else 0 for f in flags]
        F = np.asarray(flange2base, float)
        if F.shape != (len(views.names), 4, 4):
            raise InputError(f"{len(views.names)} images but flange poses of shape {F.shape}")
        block = RigBlock(views, cams, board, K, dist, n_int, method=method,
                         frames=FixedFrames({FLANGE: F}))
        none = np.zeros(0)
        nu0 = block.start(None, none)
        before = block.pixels.image_rms(block.pixels.residuals(none, nu0, strict=False))
        nu, r = fit_nuisance(block, None, none, nu0)
        X, Y, Kf, df = block.pixels.unpack(nu)
        block.set_references(X, Y, Kf, df)
        zero = np.zeros(block.n_nuisance)
        w = np.ones(block.n_rows)
        r, _, _, A, _, _ = block.normal_parts(None, none, zero, np.zeros(0, np.intp), w)
        dof = max(r.size - block.n_nuisance, 1)
        s2 = float(r @ r) / dof
        d = np.sqrt(np.clip(np.diag(A), 1e-300, None))
        cov = np.linalg.pinv(A / d[:, None] / d[None, :], rcond=1e-12, hermitian=True)
        cov = cov / d[:, None] / d[None, :] * s2
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        sl = block.pixels.slices
        pairs = {(a, b): _relative(X[a], X[b], cov, sl["camera"][a], sl["camera"][b])
                 for a in range(len(cams)) for b in range(a + 1, len(cams))}
        after = block.pixels.image_rms(block.pixels.residuals(none, zero, strict=False))
    return RigHandEyeResult(
        setup, cams, board, [board_spec], list(X), list(Y),
        [std[s] for s in sl["camera"]], [std[s] for s in sl["board"]], list(Kf), list(df),
        flags, [std[s] if k else None for s, k in zip(sl["intrinsics"], n_int, strict=True)],
        pairs, list(views.names), np.asarray(views.camera), before, after,
        float(np.sqrt(s2)), seconds=time.perf_counter() - t0, warnings=list(found))

