"""`HandEyeResult`: what `kinecal.calibration.handeye.calibrate_handeye` returns.

X, the target pose, the per-station residuals (camera pose and A X - X B), outliers,
refinement history, the uncertainty of X and the warnings; `to_dict` gives the JSON of the
``kinecal handeye`` contract (DESIGN section 4).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.handeye.errors import rms

Array = NDArray[np.float64]

__all__ = ["HandEyeResult"]


@dataclass(repr=False)
class HandEyeResult:
    """Result of `calibrate_handeye`.

    Attributes
    ----------
    X : ndarray, shape (4, 4)
        ``cam2flange`` (eye-in-hand) or ``cam2base`` (eye-to-hand), length unit of the input.
    target : ndarray, shape (4, 4)
        Fixed target pose ``Y``: ``target2base`` (eye-in-hand) or ``target2flange``.
    setup, method, refine : str
        What was run.
    rotation_deg, translation : ndarray, shape (n,)
        Per-station residual of ``G_i X C_i`` against ``Y`` (deg, length unit).
    axxb_rotation_deg, axxb_translation : ndarray, shape (n,)
        Per-station rms of the ``A X - X B`` mismatch over all pairs with that station.
    outliers : list of int
        0-based indices of stations flagged as outliers.
    history : list of float
        Cost after each iteration of the refinement (empty for closed forms).
    nfev : int
        Cost evaluations of the refinement.
    seconds : float
        Wall time.
    warnings : list of Diagnostic
        Plausibility diagnostics (`kinecal.calibration.diagnostics.handeye`).
    x_uncertainty : XUncertainty or None
        First-order uncertainty of X from the residuals (None for noise-free data).
    one_axis : dict or None
        One-axis stations (SCARA): the axis, where X's height along it came from and the
        heights (`kinecal.calibration.handeye.one_axis.one_axis_summary`); None otherwise.
    noise : StationNoise or None
        The stations' noise model the ``lm`` refinement weighed them by: the camera's
        rotation, the translation and the robot's rotation, estimated from the residuals
        or fixed (`kinecal.calibration.handeye.noise`); None for other refiners.
    """

    X: Array
    target: Array
    setup: str
    method: str
    refine: str
    rotation_deg: Array
    translation: Array
    axxb_rotation_deg: Array
    axxb_translation: Array
    outliers: list[int] = field(default_factory=list)
    history: list[float] = field(default_factory=list)
    nfev: int = 0
    seconds: float = 0.0
    warnings: list = field(default_factory=list)
    x_uncertainty: Any = None
    one_axis: dict[str, Any] | None = None
    noise: Any = None

    @property
    def rotation_rms_deg(self) -> float:
        """Rms of the station rotation residuals (deg)."""
        return rms(self.rotation_deg)

    @property
    def translation_rms(self) -> float:
        """Rms of the station translation residuals (length unit)."""
        return rms(self.translation)

    def __repr__(self) -> str:
        t = self.X[:3, 3]
        return (f"<HandEyeResult {self.setup}, {self.method}+{self.refine}: "
                f"{len(self.rotation_deg)} stations, X translation ({t[0]:.4g}, {t[1]:.4g}, "
                f"{t[2]:.4g}), residual rms "
                f"{self.rotation_rms_deg:.3g} deg / {self.translation_rms:.3g}, "
                f"{len(self.outliers)} outliers>")

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict with the keys of the ``kinecal handeye`` contract (DESIGN sec. 4)."""
        return {
            "X": self.X.tolist(),
            "target": self.target.tolist(),
            "setup": self.setup,
            "method": self.method,
            "refine": self.refine,
            "rotation_rms_deg": self.rotation_rms_deg,
            "translation_rms": self.translation_rms,
            "stations": [
                {"rotation_deg": float(r), "translation": float(t)}
                for r, t in zip(self.rotation_deg, self.translation, strict=True)
            ],
            "axxb_stations": [
                {"rotation_deg": float(r), "translation": float(t)}
                for r, t in zip(self.axxb_rotation_deg, self.axxb_translation, strict=True)
            ],
            "outliers": list(self.outliers),
            "nfev": self.nfev,
            "seconds": self.seconds,
            "x_uncertainty": None if self.x_uncertainty is None else self.x_uncertainty.to_dict(),
            "one_axis": self.one_axis,
            "noise": None if self.noise is None else self.noise.to_dict(),
            "warnings": [d.to_dict() for d in self.warnings],
        }
