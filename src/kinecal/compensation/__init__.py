"""Compensation, the workflow's *apply* step: put a calibrated model to work on a program.

Builds on `kinecal.kinematics` (inverse kinematics) and on calibration results; nothing in
`kinecal.calibration` imports it. No paper: this is the job of RoboDK's "filter program".

Public entry points
-------------------
`compensate` (`api`)
    Compensated joints of a joint program or of Cartesian targets, and filtered targets
    -> `CompensationResult` (`result`).
`inputs`
    Reading the calibrated and nominal models, programs and their options.
`same_arm`
    The check that a calibrated and a nominal model describe the same arm (best rigid
    registration of their tool poses).
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "compensate": "kinecal.compensation.api",
    "CompensationResult": "kinecal.compensation.result",
})
