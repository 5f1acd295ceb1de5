"""`CalibrationResult`: identified geometry, uncertainty, before/after statistics, JSON."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._files import write_text_atomic
from kinecal.calibration.identifiability import IdentifiabilityReport
from kinecal.calibration.uncertainty import Uncertainty
from kinecal.diagnostics import Diagnostic
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope, envelope_entry
from kinecal.kinematics.serial.model import SerialModel
from kinecal.metrology.stats import error_stats
from kinecal.metrology.units import DisplayUnit, display_unit

__all__ = ["CalibrationResult"]

Array = NDArray[np.float64]

#: poses per block of `CalibrationResult.predicted_position_error`
_PREDICT_BLOCK = 4096


def _finite(obj: Any) -> Any:
    """`obj` with every non-finite float (nested in dicts and lists) replaced by None."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, float | np.floating) and not np.isfinite(obj):
        return None
    return obj


@dataclass(repr=False)
class CalibrationResult:
    """Outcome of `kinecal.calibrate`.

    Attributes
    ----------
    model : SerialModel
        The calibrated model.
    nominal_model : SerialModel
        The model calibrated from.
    method : str
        Solver name.
    free : list of str
        Free (identified) parameters.
    params : ndarray, shape (n_params,)
        Identified full parameter vector in the Python API's units: model length unit and
        **radians** (`parameter_table` and the JSON give the model file's units, degrees
        for a ``deg`` model).
    std : ndarray, shape (n_params,)
        Standard errors (length unit, rad): 0 for parameters that were not free (held at
        nominal), ``inf`` for free parameters the poses cannot identify individually (only
        combinations of them are determined; ``null`` in the JSON).
    covariance : ndarray, shape (n_free, n_free)
        Covariance of the free parameters on their identifiable subspace,
        ``sigma^2 (J^T W J)^+`` with ``sigma^2 = RSS / (m - rank)`` (see
        `kinecal.calibration.uncertainty`); meaningful only for identifiable combinations.
    identifiability : IdentifiabilityReport
        Analysis of the candidate parameters on the calibration poses.
    errors_before, errors_after : ndarray, shape (N,)
        Distance errors on the calibration poses (length unit).
    val_before, val_after : ndarray, shape (N_val,) or None
        Distance errors on the validation poses.
    q_calibration, q_validation : ndarray, shape (N, n_joints), optional
        Joint angles (rad) of the calibration and validation poses.
    marker_calibration, marker_validation : ndarray of int, shape (N,), optional
        Marker index of each of those poses (models with several markers).
    outliers : list of int
        0-based calibration rows flagged as outliers (every row of a pose measured at
        several markers: `kinecal.calibration.diagnostics.observations`): left out of the
        last fit and of the standard errors with a robust loss, only reported with
        ``linear``.
    warnings : list of Diagnostic
        Plausibility diagnostics of this calibration (`kinecal.diagnostics`); also in the
        JSON (``warnings: [{code, message}]``), the summary and the report.
    uncertainty : Uncertainty, optional
        Identifiable subspace and null space of the fit (`kinecal.calibration.uncertainty`).
    lost : list of str
        Parameters that well-spread poses identify but these poses do not
        (``rank-deficient``): the model's uncertainty away from the poses is unbounded.
    conditions : dict of str to ndarray
        The measurement conditions the files gave (``temperature`` deg C, ``time`` s) per
        calibration pose, and ``validation_temperature``, ``validation_time`` per
        validation pose: the report plots the residual against them.
    """

    model: SerialModel
    nominal_model: SerialModel
    method: str
    free: list[str]
    params: Array
    std: Array
    covariance: Array
    identifiability: IdentifiabilityReport
    errors_before: Array
    errors_after: Array
    val_before: Array | None = None
    val_after: Array | None = None
    seed: int | None = None
    iterations: int = 0
    evaluations: int = 0
    seconds: float = 0.0
    history: list[float] = field(default_factory=list)
    outliers: list[int] = field(default_factory=list)
    message: str = ""
    success: bool = True
    sigma: float = float("nan")
    extra: dict[str, Any] = field(default_factory=dict)
    q_calibration: Array | None = None
    q_validation: Array | None = None
    marker_calibration: NDArray[np.intp] | None = None
    marker_validation: NDArray[np.intp] | None = None
    warnings: list[Diagnostic] = field(default_factory=list)
    uncertainty: Uncertainty | None = None
    lost: list[str] = field(default_factory=list)
    conditions: dict[str, Array] = field(default_factory=dict)

    # ------------------------------------------------------------------ numbers
    @property
    def envelope(self) -> JointEnvelope | None:
        """The joint readings the calibration saw, per joint the lowest and highest
        (`kinecal.kinematics.serial.joint_errors_envelope`); None without them."""
        if self.q_calibration is None or len(self.q_calibration) == 0:
            return None
        return JointEnvelope.of(self.q_calibration, [k != "prismatic" for k in
                                                     self.nominal_model.joint_kinds])

    @property
    def calibration_stats(self) -> dict[str, dict[str, float]]:
        """Before/after statistics on the calibration poses."""
        return {"before": error_stats(self.errors_before), "after": error_stats(self.errors_after)}

    @property
    def validation_stats(self) -> dict[str, dict[str, float]] | None:
        """Before/after statistics on the validation poses (None without validation)."""
        if self.val_before is None or self.val_after is None:
            return None
        return {"before": error_stats(self.val_before), "after": error_stats(self.val_after)}

    def position_groups(self) -> dict[str, dict[str, dict[str, float]]]:
        """``{"calibration": stats, "validation": stats}`` of the position errors (the
        validation entry only with validation poses)."""
        groups = {"calibration": self.calibration_stats}
        if self.validation_stats is not None:
            groups["validation"] = self.validation_stats
        return groups

    def rotation_groups(self) -> dict[str, dict[str, dict[str, float]]]:
        """The same for orientation errors (degrees); empty without measured orientations."""
        return dict(self.extra.get("rotation_deg") or {})

    @property
    def improvement_percent(self) -> float:
        """Reduction of the mean error, on validation poses when given (else calibration)."""
        s = self.validation_stats or self.calibration_stats
        before, after = s["before"]["mean"], s["after"]["mean"]
        return float(100.0 * (before - after) / before) if before > 0 else 0.0

    def position_covariance(self, q: Array, marker: NDArray[np.intp] | None = None) -> Array:
        """Covariance ``(N, 3, 3)`` of the calibrated model's tool positions at `q`.

        First-order propagation of the parameter covariance: ``J C J^T`` with ``J`` the
        identification Jacobian of the free parameters at the identified values (length
        unit squared). It is the uncertainty the calibration leaves in the model, not the
        instrument's noise. `marker`: the marker index per pose (several markers).
        """
        idx = self.nominal_model.index(self.free)
        J = self.nominal_model.identification_jacobian(q, self.params, marker=marker)[:, :, idx]
        return J @ self.covariance @ np.swapaxes(J, 1, 2)

    def predicted_position_error(self, q: Array, marker: NDArray[np.intp] | None = None
                                 ) -> Array:
        """RMS distance error ``(N,)`` of the calibrated model at `q` due to the parameter
        uncertainty: ``sqrt(trace(J C J^T))`` (length unit); checked by Monte Carlo in the
        tests. ``inf`` where it is not bounded: at poses that see a combination of free
        parameters the calibration poses do not determine, and everywhere when the poses
        left parameters undetermined that well-spread poses identify (`lost`)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if self.lost:
            return np.full(q.shape[0], np.inf)
        idx = self.nominal_model.index(self.free)
        pred = np.empty(q.shape[0])
        # in blocks of poses: the Jacobian of all poses at once would add about 1.5 kB per
        # pose to the peak memory of writing a result
        for s in range(0, q.shape[0], _PREDICT_BLOCK):
            rows = slice(s, s + _PREDICT_BLOCK)
            J = self.nominal_model.identification_jacobian(
                q[rows], self.params, marker=None if marker is None else marker[rows])[:, :, idx]
            # trace(J C J^T) per pose, without the 3 x 3 products
            p = np.sqrt(np.clip(np.einsum("nij,jk,nik->n", J, self.covariance, J,
                                          optimize=True), 0, None))
            if self.uncertainty is not None:
                p = np.where(self.uncertainty.bounded(J).all(axis=1), p, np.inf)
            pred[rows] = p
        return pred

    @property
    def bounded(self) -> bool:
        """False when the poses leave parameters undetermined that well-spread poses
        identify: the model's uncertainty away from the calibration poses is unbounded."""
        return not self.lost

    def predicted_error_summary(self) -> dict[str, float | None]:
        """Mean `predicted_position_error` over the calibration and validation poses
        (``inf`` when not bounded, None when there are no such poses)."""
        out: dict[str, float | None] = {"calibration_mean": None, "validation_mean": None}
        if not np.isfinite(self.covariance).all():
            return out
        for key, q, m in (("calibration_mean", self.q_calibration, self.marker_calibration),
                          ("validation_mean", self.q_validation, self.marker_validation)):
            if q is not None and len(q):
                out[key] = float(self.predicted_position_error(q, m).mean())
        return out

    def unidentifiable_free(self) -> list[str]:
        """Free parameters the poses cannot identify individually (standard error ``inf``)."""
        idx = self.nominal_model.index(self.free)
        return [n for n, k in zip(self.free, idx, strict=True) if not np.isfinite(self.std[k])]

    def unidentifiable(self) -> list[str]:
        """Every parameter the poses do not identify: the analysis' unidentifiable ones
        (held at nominal) and the free ones without a finite standard error, model order."""
        bad = set(self.identifiability.unidentifiable) | set(self.unidentifiable_free())
        return [n for n in self.nominal_model.parameter_names if n in bad]

    def _unit_scale(self) -> Array:
        s = 180.0 / np.pi if self.nominal_model.angle_unit == "deg" else 1.0
        return np.where(self.nominal_model.is_angle(), s, 1.0)

    def parameter_table(self) -> dict[str, dict[str, Any]]:
        """``{name: {nominal, identified, std, free}}`` in the model file's units.

        Angles in the model file's angle unit (degrees for a ``deg`` model), whereas
        `params` and `std` are in radians. ``std`` is ``inf`` for a free parameter the
        poses cannot identify (``null`` in `to_dict`), 0 for one held at nominal.
        """
        conv = self._unit_scale()
        nominal = self.nominal_model.nominal * conv
        ident = self.params * conv
        std = self.std * conv
        free = set(self.free)
        return {
            n: {"nominal": float(nominal[k]), "identified": float(ident[k]),
                "std": float(std[k]), "free": n in free}
            for k, n in enumerate(self.nominal_model.parameter_names)
        }

    def covariance_table(self) -> dict[str, Any]:
        """``{parameters, matrix}``: the covariance of the free parameters (in `free`'s
        order) in the model file's units, angles in its angle unit; what ``kinecal check``
        propagates to the poses it judges (docs/robot-life.md)."""
        conv = self._unit_scale()[self.nominal_model.index(self.free)]
        return {"parameters": list(self.free),
                "matrix": (np.asarray(self.covariance) * np.outer(conv, conv)).tolist()}

    def to_dict(self) -> dict[str, Any]:
        """The calibration JSON of DESIGN section 4 (lengths in the model unit).

        Non-finite numbers become ``null`` (a standard error of a parameter the poses cannot
        identify, an unbounded predicted error); ``unidentifiable`` lists every parameter the
        poses do not identify, free or held; ``warnings`` holds ``[{code, message}]``.
        """
        from kinecal import __version__
        from kinecal.calibration.serial.frames import frames_entry

        rep = self.identifiability
        out: dict[str, Any] = {
            "kinecal": __version__,
            "model": self.nominal_model.name,
            "method": self.method,
            "seed": self.seed,
            "length_unit": self.nominal_model.length_unit,
            "angle_unit": self.nominal_model.angle_unit,
            "parameters": self.parameter_table(),
            "frames": frames_entry(self.nominal_model, self.params, self.extra),
            "free": list(self.free),
            "covariance": self.covariance_table(),
            "unidentifiable": self.unidentifiable(),
            "confounded_with": rep.confounded_with,
            "rank": rep.rank,
            "condition_number": float(rep.condition_number),
            "observability": rep.observability,
            "calibration": {"n": int(self.errors_before.size), **self.calibration_stats},
            "validation": None,
            "improvement_percent": self.improvement_percent,
            "iterations": int(self.iterations),
            "evaluations": int(self.evaluations),
            "seconds": float(self.seconds),
            "sigma": float(self.sigma),
            "history": [float(h) for h in self.history],
            "outliers": [int(i) for i in self.outliers],
            "success": bool(self.success),
            "message": self.message,
        }
        if self.validation_stats is not None:
            out["validation"] = {"n": int(self.val_before.size), **self.validation_stats}
        out["predicted_error"] = {**self.predicted_error_summary(), "bounded": self.bounded}
        if self.lost:
            out["not_determined"] = list(self.lost)
        if self.envelope is not None:
            out["envelope"] = envelope_entry(self.nominal_model, self.envelope)
        out.update(self.extra)
        if "noise" in self.extra:  # the stated noise: its test and known-noise uncertainty
            from kinecal.calibration.diagnostics.noise import noise_entry

            out["noise"] = noise_entry(self)
        out["warnings"] = [d.to_dict() for d in self.warnings]
        return _finite(out)

    def to_json(self, path: str | Path) -> None:
        """Write `to_dict` as JSON (atomic)."""
        text = json.dumps(self.to_dict(), indent=2, default=float)
        write_text_atomic(path, text + "\n")

    def save_model(self, path: str | Path) -> None:
        """Write the calibrated model file (read back by `kinecal.load_model`)."""
        from kinecal.io.models import save_model

        save_model(self.model, path)

    # ------------------------------------------------------------------ text
    def display_unit(self, unit: str | None = None) -> DisplayUnit:
        """The unit `summary` shows lengths in (`kinecal.metrology.units.display_unit`):
        `unit`, or by default the model's (millimetres for a model in metres whose errors
        stay below 1 m)."""
        largest = [s["before"]["max"] for s in self.position_groups().values()]
        return display_unit(self.nominal_model.length_unit, unit, largest)

    def summary(self, unit: str | None = None) -> str:
        """Plain-text summary: identifiability, before/after table, largest corrections.

        `unit` (``mm``, ``um``, ``m``, or ``auto``/None: `display_unit`) is the length unit
        of the text only; the result's numbers stay in the model's unit
        (`kinecal.calibration.serial.result_summary.summary_text`).
        """
        from kinecal.calibration.serial.result_summary import summary_text

        return summary_text(self, unit)

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        shown = self.display_unit()
        s = self.validation_stats or self.calibration_stats
        where = "validation" if self.validation_stats is not None else "calibration"
        return (f"<{type(self).__name__} {self.nominal_model.name} ({self.method}): "
                f"{len(self.free)} free parameters, {where} mean "
                f"{s['before']['mean'] * shown.factor:.4g} -> "
                f"{s['after']['mean'] * shown.factor:.4g} {shown.name}>")

    # ------------------------------------------------------------------ figures
    def plot(self, kind: str = "errors", ax: Any = None) -> Any:
        """Draw a figure for notebooks: ``errors`` (per pose), ``histogram`` or
        ``convergence``. Returns the matplotlib Axes."""
        from kinecal.report.figures import plot_calibration

        return plot_calibration(self, kind=kind, ax=ax)

    def report(self, path: str | Path) -> Path:
        """Write a self-contained HTML report; returns its path."""
        from kinecal.report.html import calibration_report

        return calibration_report(self, path)
