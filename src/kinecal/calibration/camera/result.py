"""`Stations` (the input) and `ArmCameraResult` (the outcome) of an arm calibration from
camera images."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._files import write_text_atomic
from kinecal._reproducible import seconds_text
from kinecal.calibration.camera.identify import CameraIdentifiability
from kinecal.calibration.uncertainty import Uncertainty
from kinecal.diagnostics import Diagnostic
from kinecal.kinematics.serial.model import SerialModel

Array = NDArray[np.float64]

__all__ = ["ArmCameraResult", "Stations"]


@dataclass
class Stations:
    """Stations of an arm calibration from images: joints and detected corners.

    Attributes
    ----------
    q : ndarray, shape (n, n_joints)
        Joint readings (rad; prismatic: length unit).
    points : list of ndarray, shape (N_i, 3)
        Board coordinates of the corners detected in station i.
    pixels : list of ndarray, shape (N_i, 2)
        Their pixel positions.
    target2cam : ndarray, shape (n, 4, 4), optional
        Board pose per image (PnP), for the closed-form start.
    names : list of str
        Image names.
    """

    q: Array
    points: list[Array]
    pixels: list[Array]
    target2cam: Array | None = None
    names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.q = np.atleast_2d(np.asarray(self.q, float))
        if not self.names:
            self.names = [f"station_{i + 1}" for i in range(len(self.q))]


def _rms(v: Array) -> float:
    v = np.asarray(v, float)
    return float(np.sqrt(np.mean(v**2))) if v.size else float("nan")


def _pixel_stats(station_rms: Array, keep: Array | None = None) -> dict[str, Any]:
    s = np.asarray(station_rms, float)
    if keep is not None:
        s = s[keep]
    return {"n": int(s.size), "rms_px": _rms(s), "max_station_rms_px":
            float(s.max()) if s.size else float("nan"),
            "median_station_rms_px": float(np.median(s)) if s.size else float("nan")}


@dataclass
class ArmCameraResult:
    """Outcome of `kinecal.calibration.camera.calibrate_arm_camera`.

    Attributes
    ----------
    model, nominal_model : SerialModel
        The calibrated arm (parameters the camera cannot see held at nominal) and the
        nominal one.
    setup : str
    free : list of str
        The arm's free (identified) parameters.
    params, std : ndarray, shape (n_params,)
        Identified parameter vector and standard errors (0: held; inf: not estimable).
    X, board_pose : ndarray, shape (4, 4)
        Camera mount (``cam2flange`` / ``cam2base``) and board pose (``target2base`` /
        ``target2flange``), calibrated with the arm.
    X_handeye, board_handeye : ndarray, shape (4, 4)
        The same from the hand-eye refinement with the arm at nominal (the "before").
    K, dist : ndarray
        Intrinsics (refined when asked).
    nuisance_names : list of str
    nuisance_std : ndarray
        Standard errors of the nuisance parameters (rad, length unit, px / coefficients).
    identifiability : CameraIdentifiability
    uncertainty : Uncertainty
        On the stacked vector ``[free arm parameters, nuisance]``.
    station_names : list of str
    before_px, after_px : ndarray, shape (n,)
        RMS corner residual per station with the arm at nominal (X and board refined) and
        calibrated (px).
    outliers : list of int
        Stations flagged as outliers (0-based into `station_names`).
    sigma_px : float
        Corner noise per coordinate (px), from the residual.
    val_before_px, val_after_px : ndarray or None
        The same for the validation stations.
    """

    model: SerialModel
    nominal_model: SerialModel
    setup: str
    free: list[str]
    params: Array
    std: Array
    X: Array
    board_pose: Array
    X_handeye: Array
    board_handeye: Array
    K: Array
    dist: Array
    nuisance_names: list[str]
    nuisance_std: Array
    identifiability: CameraIdentifiability
    uncertainty: Uncertainty
    station_names: list[str]
    before_px: Array
    after_px: Array
    outliers: list[int]
    sigma_px: float
    loss: str = "linear"
    val_before_px: Array | None = None
    val_after_px: Array | None = None
    val_names: list[str] = field(default_factory=list)
    residuals: list[Array] = field(default_factory=list)
    iterations: int = 0
    evaluations: int = 0
    history: list[float] = field(default_factory=list)
    success: bool = True
    seconds: float = 0.0
    warnings: list[Diagnostic] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ numbers
    @property
    def inliers(self) -> Array:
        """Mask ``(n,)`` of the stations not flagged as outliers."""
        keep = np.ones(len(self.station_names), bool)
        keep[self.outliers] = False
        return keep

    @property
    def X_std(self) -> tuple[Array, Array]:
        """Standard deviations of X: rotation (deg, about X's axes) and translation."""
        return np.degrees(self.nuisance_std[0:3]), self.nuisance_std[3:6]

    @property
    def held(self) -> list[str]:
        """The model's calibratable parameters held at nominal (not free)."""
        free = set(self.free)
        return [n for n in self.nominal_model.calibratable if n not in free]

    def parameter_table(self) -> dict[str, dict[str, Any]]:
        """``{name: {nominal, identified, std, free}}`` in the model file's units (as
        `kinecal.calibration.serial.result.CalibrationResult.parameter_table`)."""
        nom = self.nominal_model
        conv = np.where(nom.is_angle(), 180.0 / np.pi if nom.angle_unit == "deg" else 1.0, 1.0)
        free = set(self.free)
        return {n: {"nominal": float(nom.nominal[k] * conv[k]),
                    "identified": float(self.params[k] * conv[k]),
                    "std": float(self.std[k] * conv[k]), "free": n in free}
                for k, n in enumerate(nom.parameter_names)}

    def to_dict(self) -> dict[str, Any]:
        """JSON of ``kinecal calibrate --images`` (docs/arm-from-images.md)."""
        from kinecal import __version__
        from kinecal.calibration.serial.result import _finite

        xr, xt = self.X_std
        keep = self.inliers
        out: dict[str, Any] = {
            "kinecal": __version__, "model": self.nominal_model.name, "method": "lm",
            "kind": "camera", "setup": self.setup,
            "length_unit": self.nominal_model.length_unit,
            "angle_unit": self.nominal_model.angle_unit,
            "parameters": self.parameter_table(), "free": list(self.free),
            "held": self.held,
            "unidentifiable": list(self.identifiability.report.unidentifiable),
            "identifiability": self.identifiability.to_dict(),
            "not_seen": list(self.identifiability.sentences),
            "X": self.X.tolist(),
            "X_frame": "cam2flange" if self.setup == "eye-in-hand" else "cam2base",
            "X_std": {"rotation_deg": xr.tolist(), "translation": xt.tolist()},
            "board_pose": self.board_pose.tolist(),
            "board_frame": "target2base" if self.setup == "eye-in-hand" else "target2flange",
            "X_handeye": self.X_handeye.tolist(), "intrinsics": {
                "K": self.K.tolist(), "dist": self.dist.tolist(),
                "refined": len(self.nuisance_names) > 12},
            "calibration": {"before": _pixel_stats(self.before_px, keep),
                            "after": _pixel_stats(self.after_px, keep)},
            "validation": None, "sigma_px": self.sigma_px, "loss": self.loss,
            "stations": [{"image": n, "status": "outlier" if i in self.outliers else "used",
                          "rms_px_before": float(b), "rms_px_after": float(a)}
                         for i, (n, b, a) in enumerate(zip(self.station_names, self.before_px,
                                                           self.after_px, strict=True))],
            "outliers": [self.station_names[i] for i in self.outliers],
            "iterations": self.iterations, "evaluations": self.evaluations,
            "seconds": self.seconds, "history": [float(h) for h in self.history],
            "success": self.success,
        }
        if self.val_before_px is not None:
            out["validation"] = {"before": _pixel_stats(self.val_before_px),
                                 "after": _pixel_stats(self.val_after_px),
                                 "images": list(self.val_names)}
        out.update(self.extra)
        out["warnings"] = [d.to_dict() for d in self.warnings]
        return _finite(out)

    def to_json(self, path: str | Path) -> None:
        """Write `to_dict` as JSON (atomic)."""
        write_text_atomic(path, json.dumps(self.to_dict(), indent=2, default=float) + "\n")

    def save_model(self, path: str | Path) -> None:
        """Write the calibrated model file (read back by `kinecal.load_model`)."""
        from kinecal.io.models import save_model

        save_model(self.model, path)

    # ------------------------------------------------------------------ text
    def summary(self, unit: str | None = None) -> str:
        """Plain-text summary; `unit` (``mm``, ``um``, ``m``, or ``auto``/None: the model's)
        is the length unit of the text only (`kinecal.metrology.units.display_unit`)."""
        from kinecal.metrology.units import DisplayUnit, display_unit

        nom = self.nominal_model
        shown = DisplayUnit(nom.length_unit, 1.0) if unit in (None, "auto") else \
            display_unit(nom.length_unit, unit)
        keep = self.inliers
        b, a = _rms(self.before_px[keep]), _rms(self.after_px[keep])
        rep = self.identifiability.report
        lines = [
            f"model {nom.name}: {len(self.station_names)} stations "
            f"({len(self.outliers)} outlier(s)), {self.setup}; {len(self.free)} arm "
            f"parameters free (rank {rep.rank} of {len(rep.names)} beside X and the board)",
            f"reprojection RMS: {b:.3f} px with the arm at nominal (X and board refined) -> "
            f"{a:.3f} px calibrated (corner sigma {self.sigma_px:.3f} px)",
        ]
        if self.val_before_px is not None:
            lines.append(f"validation ({len(self.val_before_px)} stations): "
                         f"{_rms(self.val_before_px):.3f} px -> {_rms(self.val_after_px):.3f} px")
        lines += ["what the camera cannot see (held at nominal):"]
        lines += [f"  {s}" for s in self.identifiability.sentences]
        conv = np.where(nom.is_angle(), 180.0 / np.pi if nom.angle_unit == "deg" else 1.0, 1.0)
        idx = nom.index(self.free)
        dev = (self.params - nom.nominal) * conv
        order = idx[np.argsort(-np.abs(dev[idx] / np.where(nom.is_angle()[idx], 0.01, 0.1)))]
        lines.append("largest corrections (identified - nominal, 1 sigma):")
        for k in order[:8]:
            angle = nom.is_angle()[k]
            u, g = (nom.angle_unit, 1.0) if angle else (shown.name, shown.factor)
            lines.append(f"  {nom.parameter_names[k]:10s} {dev[k] * g:+.4f} {u} "
                         f"(+- {self.std[k] * conv[k] * g:.4f})")
        xr, xt = self.X_std
        lines.append("X std (1 sigma): rotation " + ", ".join(f"{v:.4f}" for v in xr)
                     + " deg, translation " + ", ".join(f"{v * shown.factor:.4f}" for v in xt)
                     + f" {shown.name}")
        if "intrinsics_line" in self.extra:
            lines.append(str(self.extra["intrinsics_line"]).replace("with X", "with the arm"))
        lines.append(f"{self.iterations} iterations, {self.evaluations} evaluations"
                     + seconds_text(self.seconds))
        if self.outliers:
            lines.append("outlier stations: " + ", ".join(self.station_names[i]
                                                          for i in self.outliers))
        if self.warnings:
            lines += ["", f"warnings ({len(self.warnings)}):"]
            lines += [f"  [{d.code}] {d.message}" for d in self.warnings]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()
