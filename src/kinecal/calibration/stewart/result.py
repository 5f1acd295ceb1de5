"""Result of a parallel-link CMM calibration: statistics, JSON, text and report."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.calibration.stewart.data import ARCSEC
from kinecal.diagnostics import Diagnostic, expect
from kinecal.kinematics.stewart.platform import N_PARAMETERS, PARAMETER_NAMES, StewartPlatform
from kinecal.metrology.units import display_unit
from kinecal.spatial import matrix_from_rpy, pose_errors, transform_from

__all__ = ["StewartCalibrationResult", "abs_stats", "pose_prediction_errors"]

Array = NDArray[np.float64]


def abs_stats(err: Array) -> dict[str, float]:
    """``{mean, rms, std, max}`` of the absolute values of `err` (any shape, flattened):
    the leg-residual statistics of the Stewart JSON (population std)."""
    e = np.abs(np.asarray(err, dtype=float)).ravel()
    return {
        "mean": float(e.mean()),
        "rms": float(np.sqrt(np.mean(e**2))),
        "std": float(e.std()),
        "max": float(e.max()),
    }


def pose_prediction_errors(
    geom: StewartPlatform, legs: ArrayLike, true_poses: ArrayLike
) -> dict[str, dict[str, float]]:
    """Probe poses predicted from leg readings by `geom` (Newton FK) vs the true poses.

    Returns
    -------
    dict
        ``position`` statistics (length unit) and ``rotation`` statistics (arcsec).
    """
    x = np.asarray(true_poses, dtype=float)
    with expect("leg-range"):  # the data checks judge the leg range (check_leg_range)
        fk = geom.forward(legs, x0=x, on_failure="flag")
    Test = transform_from(matrix_from_rpy(fk.poses[:, 3:]), fk.poses[:, :3])
    Tref = transform_from(matrix_from_rpy(x[:, 3:]), x[:, :3])
    rot, pos = pose_errors(Test, Tref)
    return {"position": abs_stats(pos), "rotation_arcsec": abs_stats(rot / ARCSEC)}


@dataclass(repr=False)
class StewartCalibrationResult:
    """Identified geometry and error statistics (JSON via `to_dict`).

    Attributes
    ----------
    geometry : StewartPlatform
        Calibrated machine.
    nominal : StewartPlatform
        Starting (nominal) machine.
    std : ndarray, shape (42,)
        Standard errors of the parameters (length unit).
    rank, condition_number : int, float
        Identifiability of the 42 parameters on the calibration poses.
    calibration, validation : dict
        ``n`` and leg-reading error statistics ``before`` / ``after`` (length unit).
    iterations, evaluations : int
    seconds : float
    history : list of float
        RMS leg residual at the start and the end (length unit).
    warnings : list of Diagnostic
        Plausibility diagnostics (`kinecal.calibration.diagnostics.stewart`).
    length_unit : str
        The geometry's length unit (for the text and the JSON).
    outliers : list of int
        0-based calibration poses whose leg residuals are outliers (median/MAD rule).
    bounded : bool
        False when the poses identify fewer parameters than well-spread workspace poses
        (``std`` is then ``inf`` for the undetermined ones).
    errors_before, errors_after : ndarray, shape (N,), optional
        Norm of the six leg residuals of each calibration pose (length unit).

    Notes
    -----
    ``std`` is ``inf`` (``null`` in the JSON) for a parameter the poses cannot identify:
    the covariance is restricted to the combinations they determine
    (`kinecal.calibration.uncertainty`).
    """

    geometry: StewartPlatform
    nominal: StewartPlatform
    std: Array
    rank: int
    condition_number: float
    unidentifiable: list[str]
    calibration: dict
    validation: dict | None
    iterations: int
    evaluations: int
    seconds: float
    history: list[float] = field(default_factory=list)
    warnings: list[Diagnostic] = field(default_factory=list)
    length_unit: str = "m"
    outliers: list[int] = field(default_factory=list)
    bounded: bool = True
    errors_before: Array | None = None
    errors_after: Array | None = None

    def to_dict(self) -> dict:
        """The DESIGN calibration JSON layout, for the Stewart parameters."""
        params = {
            name: {"nominal": float(a), "identified": float(b),
                   "std": float(s) if np.isfinite(s) else None, "free": True}
            for name, a, b, s in zip(
                PARAMETER_NAMES,
                self.nominal.parameters,
                self.geometry.parameters,
                self.std,
                strict=True,
            )
        }
        ref = self.validation if self.validation is not None else self.calibration
        b, a = ref["before"]["rms"], ref["after"]["rms"]
        improve = 100.0 * (1.0 - a / b) if b > 0 else 0.0
        return {
            "model": self.nominal.name,
            "method": "lm",
            "length_unit": self.length_unit,
            "parameters": params,
            "unidentifiable": self.unidentifiable,
            "rank": self.rank,
            "condition_number": self.condition_number,
            "calibration": self.calibration,
            "validation": self.validation,
            "improvement_percent": improve,
            "iterations": self.iterations,
            "evaluations": self.evaluations,
            "seconds": self.seconds,
            "history": self.history,
            "outliers": [int(i) for i in self.outliers],
            "bounded": bool(self.bounded),
            "warnings": [d.to_dict() for d in self.warnings],
        }

    def __repr__(self) -> str:
        part = self.validation if self.validation is not None else self.calibration
        u, f = display_unit(self.length_unit, None, [part["before"]["rms"]])
        where = "validation" if self.validation is not None else "calibration"
        return (f"<StewartCalibrationResult {self.nominal.name}: rank {self.rank}/"
                f"{N_PARAMETERS}, {where} leg rms {part['before']['rms'] * f:.4g} -> "
                f"{part['after']['rms'] * f:.4g} {u}>")

    def summary(self, unit: str | None = None) -> str:
        """Text table of the before/after leg-reading errors, the undetermined parameters
        and the warnings. `unit`: the length unit of the text (``mm``, ``um``, ``m``; by
        default the geometry's, millimetres for one in metres with errors below 1 m;
        `kinecal.metrology.units.display_unit`)."""
        parts = [p for p in (self.calibration, self.validation) if p is not None]
        u, f = display_unit(self.length_unit, unit, [p["before"]["rms"] for p in parts])
        lines = [f"rank {self.rank}/{N_PARAMETERS}, condition {self.condition_number:.3g}"]
        loose = [n for n, s in zip(PARAMETER_NAMES, self.std, strict=True) if not np.isfinite(s)]
        if loose:
            lines.append("not identifiable (value arbitrary, no standard error): "
                         + ", ".join(loose))
        for label, part in (("calibration", self.calibration), ("validation", self.validation)):
            if part is None:
                continue
            b, a = part["before"]["rms"], part["after"]["rms"]
            lines.append(f"{label:12s} n={part['n']:4d}  leg rms before {b * f:.4g} {u}  "
                         f"after {a * f:.4g} {u}")
        if self.outliers:
            lines.append(f"outlier poses (0-based): {self.outliers}")
        if self.warnings:
            lines += [f"warnings ({len(self.warnings)}):"]
            lines += [f"  [{d.code}] {d.message}" for d in self.warnings]
        return "\n".join(lines)

    def report(self, path: str | Path) -> Path:
        """Write a self-contained HTML report (`kinecal.report.stewart`); returns its path."""
        from kinecal.report.stewart import stewart_report

        return stewart_report(self, path)

