"""Serial-arm calibration: identify an arm's geometry from measured tool points or poses.

Papers: 000 (Hu 2005: D-H model, modified least squares sec. 4.1, real-coded GA and the
LS + GA hybrid sec. 4.2) and 002 (Zhao & Yang: Hayati model, artificial fish swarm AFSA and
SA-IAFSA). Beyond them: Levenberg-Marquardt on the analytic Jacobian restricted to the
identifiable parameters, honest uncertainty, robust losses, cross-validated error models.

Public entry points
-------------------
`calibrate` (`api`)
    ``calibrate(model, data, method="lm", free="identifiable", validate=...)`` ->
    `CalibrationResult` (`result`); a metaheuristic's answer is checked by a local
    least-squares polish (`polish`, warning ``optimizer-stalled``).
`calibrate_error_model` (`error_model`)
    Geometric plus non-geometric joint errors, chosen by cross-validation
    (`cross_validation`, `error_model_spec`, `joint_identifiability`).
`CalibrationProblem`, `resolve_free` (`problem`)
    Free parameters, scaling and residual rows (`rows`) of one calibration; solved by
    `solve` (chunked normal equations).
`parse_prior`, `resolve_prior` (`prior`)
    Priors on the free parameters (``calibrate(..., prior=...)``): the MAP rows and
    posterior (`prior_fit`), the strength of ``auto`` by cross-validation (`prior_auto`).
`simulate`, `random_configurations`, `random_errors` (`simulate`)
    Synthetic measurements of a perturbed arm.
`select_poses` (`pose_selection`)
    Observability-optimal pose sets.
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "calibrate": "kinecal.calibration.serial.api",
    "CALIBRATION_RANK_TOL": "kinecal.calibration.serial.api",
    "CALIBRATION_METHODS": "kinecal.calibration.serial.api",
    "CalibrationResult": "kinecal.calibration.serial.result",
    "calibrate_error_model": "kinecal.calibration.serial.error_model",
    "CalibrationProblem": "kinecal.calibration.serial.problem",
    "resolve_free": "kinecal.calibration.serial.problem",
    "select_poses": "kinecal.calibration.serial.pose_selection",
    "parse_prior": "kinecal.calibration.serial.prior",
    "resolve_prior": "kinecal.calibration.serial.prior",
})
