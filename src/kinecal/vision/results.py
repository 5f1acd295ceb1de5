"""The outcome of a hand-eye calibration from images (`kinecal.vision.pipeline`): one
`ImageRecord` per image (used, rejected or outlier, with the reason, detection, PnP pose and
corner residuals) and the `ImageHandEyeResult` with X, the board pose, the intrinsics used,
the refinement and the JSON of ``kinecal handeye-images --json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye import HandEyeResult
from kinecal.calibration.handeye.refinement import ReprojectionRefinement
from kinecal.vision.boards import Board
from kinecal.vision.detect import Detection
from kinecal.vision.intrinsics import CameraIntrinsics
from kinecal.vision.pnp import BoardPose

Array = NDArray[np.float64]

__all__ = ["ImageHandEyeResult", "ImageRecord"]


@dataclass
class ImageRecord:
    """What happened to one image.

    Attributes
    ----------
    name : str
    status : str
        ``used``, ``outlier`` (used for nothing after the robust refinement flagged its
        station) or ``rejected``.
    reason : str
        Why it was rejected or flagged ("" when used).
    detection : Detection or None
    pose : BoardPose or None
        PnP board pose (accepted detections).
    residuals : ndarray, shape (N, 2) or None
        Observed minus predicted corners after the refinement (px).
    """

    name: str
    status: str
    reason: str = ""
    detection: Detection | None = None
    pose: BoardPose | None = None
    residuals: Array | None = None

    @property
    def rms_px(self) -> float | None:
        """RMS corner residual after the refinement (px); None without residuals or when
        the station's board is behind the camera for the solution."""
        if self.residuals is None or not len(self.residuals):
            return None
        v = float(np.sqrt(np.mean(np.sum(self.residuals**2, axis=1))))
        return v if np.isfinite(v) else None

    @property
    def max_px(self) -> float | None:
        """Largest corner residual after the refinement (px)."""
        if self.residuals is None or not len(self.residuals):
            return None
        v = float(np.max(np.linalg.norm(self.residuals, axis=1)))
        return v if np.isfinite(v) else None

    def to_dict(self) -> dict[str, Any]:
        """The per-image entry of the JSON result."""
        det, pose = self.detection, self.pose
        return {
            "image": self.name, "status": self.status, "reason": self.reason,
            "corners": 0 if det is None else len(det.corners),
            "seen": "" if det is None else det.seen,
            "rms_px": self.rms_px, "max_px": self.max_px,
            "pnp_rms_px": None if pose is None else pose.rms_px,
            "tilt_deg": None if pose is None else pose.tilt_deg,
            "edge_width_px": (None if det is None or not np.isfinite(det.edge_width)
                              else det.edge_width),
        }


@dataclass(repr=False)
class ImageHandEyeResult:
    """Result of `calibrate_handeye_images`.

    Attributes
    ----------
    X : ndarray, shape (4, 4)
        ``cam2flange`` (eye-in-hand) or ``cam2base`` (eye-to-hand), board length unit.
    target : ndarray, shape (4, 4)
        Board pose: ``target2base`` (eye-in-hand) or ``target2flange`` (eye-to-hand).
    setup, method : str
        Set-up and the closed form that seeded the refinement.
    board : Board
    intrinsics : CameraIntrinsics
        As used (refined values when ``refine_intrinsics``).
    intrinsics_refined : bool
    records : list of ImageRecord
        One per input image, in input order.
    refinement : ReprojectionRefinement
    seed : HandEyeResult
        The pose-based solution that started the refinement.
    warnings : list of dict
        Plausibility warnings raised on the way (``code``, ``message``).
    seconds : float
    one_axis : dict or None
        The robot turned about one axis only (SCARA): the axis and X's height along it
        (`kinecal.calibration.handeye.one_axis.one_axis_summary`).
    """

    X: Array
    target: Array
    setup: str
    method: str
    board: Board
    intrinsics: CameraIntrinsics
    intrinsics_refined: bool
    records: list[ImageRecord]
    refinement: ReprojectionRefinement
    seed: HandEyeResult
    warnings: list[dict[str, str]] = field(default_factory=list)
    seconds: float = 0.0
    one_axis: dict[str, Any] | None = None

    def __repr__(self) -> str:
        t = self.X[:3, 3]
        return (f"<ImageHandEyeResult {self.setup}, board {self.board.spec}: "
                f"{len(self.records)} images, {len(self.used)} used, X translation "
                f"({t[0]:.4g}, {t[1]:.4g}, {t[2]:.4g}) mm, reprojection RMS "
                f"{self.refinement.rms_px:.3g} px>")

    @property
    def used(self) -> list[ImageRecord]:
        """Records of the images the final solution rests on."""
        return [r for r in self.records if r.status == "used"]

    @property
    def rejected(self) -> list[ImageRecord]:
        """Records of the rejected images."""
        return [r for r in self.records if r.status == "rejected"]

    @property
    def outliers(self) -> list[str]:
        """Names of the images whose station the refinement flagged."""
        return [r.name for r in self.records if r.status == "outlier"]

    @property
    def X_std(self) -> tuple[Array, Array]:
        """Standard deviations of X: rotation (deg, about X's axes), translation."""
        return self.refinement.X_std

    def to_dict(self) -> dict[str, Any]:
        """The JSON of ``kinecal handeye-images --json``."""
        xr, xt = self.refinement.X_std
        yr, yt = self.refinement.Y_std
        ref = self.refinement
        return {
            "X": self.X.tolist(),
            "X_frame": "cam2flange" if self.setup == "eye-in-hand" else "cam2base",
            "X_std": {"rotation_deg": xr.tolist(), "translation": xt.tolist()},
            "X_cov": ref.X_cov.tolist(),
            "target": self.target.tolist(),
            "target_frame": "target2base" if self.setup == "eye-in-hand" else "target2flange",
            "board_pose": self.target.tolist(),
            "target_std": {"rotation_deg": yr.tolist(), "translation": yt.tolist()},
            "setup": self.setup,
            "board": self.board.spec,
            "length_unit": "board unit (the --board lengths, mm by convention)",
            "method": self.method,
            "refine": "reprojection",
            "intrinsics": {**self.intrinsics.to_dict(), "refined": self.intrinsics_refined},
            "reprojection_rms_px": ref.rms_px,
            "corner_sigma_px": ref.sigma_px,
            "n_images": len(self.records),
            "n_used": len(self.used),
            "images": [r.to_dict() for r in self.records],
            "rejected": [{"image": r.name, "reason": r.reason} for r in self.rejected],
            "outliers": self.outliers,
            "robot_noise": (None if ref.robot_noise is None
                            else ref.robot_noise.to_dict()),
            "robot_corrections": (None if ref.corrections is None
                                  else ref.corrections.tolist()),
            "seed": {"method": self.method, "X": self.seed.X.tolist(),
                     "rotation_rms_deg": self.seed.rotation_rms_deg,
                     "translation_rms": self.seed.translation_rms},
            "one_axis": self.one_axis,
            "warnings": list(self.warnings),
            "seconds": self.seconds,
        }
