"""`ErrorModelResult` and the text of an error-model calibration.

The result of `kinecal.calibration.serial.error_model.calibrate_error_model`: a
`CalibrationResult` that also keeps the geometric calibration it started from and the
measured positions (for the report's residual maps, `kinecal.report.residual_maps`), and
whose summary adds the choice of terms (`error_model_text`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from kinecal.calibration.serial.result import CalibrationResult
from kinecal.data import Measurements

__all__ = ["ErrorModelResult", "error_model_text"]


@dataclasses.dataclass(repr=False)
class ErrorModelResult(CalibrationResult):
    """A `CalibrationResult` with joint-error terms, which also keeps what the report's
    residual maps need (`kinecal.report.residual_maps`).

    Attributes
    ----------
    geometric : CalibrationResult or None
        The geometric calibration the error model started from.
    measured_xyz : ndarray, shape (N, 3) or None
        Measured tool positions of the calibration poses.
    """

    geometric: CalibrationResult | None = None
    measured_xyz: np.ndarray | None = None

    @classmethod
    def of(cls, result: CalibrationResult, geometric: CalibrationResult,
           data: Measurements) -> ErrorModelResult:
        """`result` with its geometric calibration and the measured positions."""
        fields = {f.name: getattr(result, f.name) for f in dataclasses.fields(result)}
        return cls(**fields, geometric=geometric, measured_xyz=np.asarray(data.xyz))

    def summary(self, unit: str | None = None) -> str:
        """`CalibrationResult.summary` and the error model: the choice, its
        cross-validation table (``auto``), the step from the geometric calibration."""
        return super().summary(unit) + error_model_text(self, unit)


def error_model_text(result: CalibrationResult, unit: str | None = None) -> str:
    """Plain-text lines on the error model of `result` ("" for a plain calibration): the
    cross-validation table (``auto``), the step from the geometric calibration and the
    coefficients that are not identifiable; lengths in `result.display_unit(unit)`."""
    info = result.extra.get("error_model")
    if not info:
        return ""
    unit, f = result.display_unit(unit)
    lines = ["", "", f"error model: {info['requested']} -> {info['selected']}"]
    if info.get("candidates"):
        lines[-1] += (f" ({info['folds']}-fold cross-validation on the calibration poses, "
                      f"within and beyond their joint ranges, {info['rule']} rule)")
        lines.append(f"{'candidate':34s} {'params':>6s} {'score':>9s} {'within':>9s} "
                     f"{'beyond':>9s} {'se':>8s}")
        for row in info["candidates"]:
            mark = ("  <- chosen" if row["chosen"] else "") + ("  (best)" if row["best"] else "")
            if row["score"] is None:  # more parameters than a fold's training rows
                lines.append(f"{row['model']:34s} {row['parameters']:6d} {'-':>9s} {'-':>9s} "
                             f"{'-':>9s} {'-':>8s}  (too many parameters for these poses)")
                continue
            beyond = list(row.get("cv_blocked", {}).values())
            far = f"{np.mean(beyond) * f:9.5g}" if beyond else f"{'-':>9s}"
            lines.append(f"{row['model']:34s} {row['parameters']:6d} {row['score'] * f:9.5g} "
                         f"{row['cv_mean'] * f:9.5g} {far} {row['cv_se'] * f:8.2g}{mark}")
        lines.append(f"(mean held-out distance error [{unit}]: within = random folds, beyond "
                     "= folds blocked by joint range and time, score = their average)")
    geo = info.get("geometric", {})
    if "validation_mean" in geo and result.val_after is not None:
        lines.append(f"validation mean: geometric {geo['validation_mean'] * f:.4g} {unit} -> "
                     f"{info['selected']} {float(np.mean(result.val_after)) * f:.4g} {unit}")
    else:
        lines.append(f"calibration mean: geometric {geo['calibration_mean'] * f:.4g} {unit} -> "
                     f"{info['selected']} {float(np.mean(result.errors_after)) * f:.4g} {unit}")
    terms = result.extra.get("joint_errors")
    if terms:
        lines.append(f"joint-error coefficients: {len(terms['identifiable'])} identifiable, "
                     f"{len(terms['unidentifiable'])} held at nominal")
        for name in terms["unidentifiable"]:
            combo = terms["confounded_with"].get(name, {})
            top = sorted(combo.items(), key=lambda kv: -abs(kv[1]))[:3]
            if not combo:
                lines.append(f"  {name}: no effect on these poses")
                continue
            what = ", ".join(f"{c:+.3g} {n}" for n, c in top) + (" ..." if len(combo) > 3
                                                                  else "")
            lines.append(f"  {name}: confounded with {what}")
    return "\n".join(lines)
