"""Geometry calibration of the parallel-link (Stewart-platform) CMM of paper 004.

Paper 004 (Liu, Liu & Wei 2008) solves the machine's forward kinematics; kinecal also
identifies its 42 geometric parameters (base and platform joints, leg offsets) from measured
probe poses and leg readings.

Public entry points
-------------------
`calibrate_stewart` (`calibrate`)
    Levenberg-Marquardt on the inverse-kinematics residual (`identification`: analytic,
    block-structured Jacobian and identifiability) -> `StewartCalibrationResult` (`result`).
`StewartData`, `simulate_stewart`, `perturb_geometry` (`data`)
    Measurements of the machine, real or simulated.
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "calibrate_stewart": "kinecal.calibration.stewart.calibrate",
    "StewartCalibrationResult": "kinecal.calibration.stewart.result",
    "StewartData": "kinecal.calibration.stewart.data",
    "simulate_stewart": "kinecal.calibration.stewart.data",
    "perturb_geometry": "kinecal.calibration.stewart.data",
})
