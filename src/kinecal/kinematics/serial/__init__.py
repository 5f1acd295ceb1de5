"""Serial arms: kinematic model, forward kinematics, Jacobians and inverse kinematics.

Papers: 000 (Hu 2005, standard D-H, eq. 1) and 002 (Zhao & Yang, Hayati's modified D-H for
nearly parallel axes). Conventions are written once in docs/conventions.md.

Public entry points
-------------------
`SerialModel` (`model`)
    The arm: a chain of elementary motions (`motions`, `chain`), base and tool frames,
    markers (`markers`); batch FK and the identification Jacobian (`kinematics`, `compose`,
    `sweep`, `folded`).
`JointErrors`, `joint_errors_for` (`joint_errors`)
    Non-geometric joint-angle corrections: compliance (`gravity`), harmonics, encoder scale.
`solve_ik` (`ik`)
    Batch inverse kinematics on the analytic joint Jacobian (`ik_lm`).
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "SerialModel": "kinecal.kinematics.serial.model",
    "JointErrors": "kinecal.kinematics.serial.joint_errors",
    "joint_errors_for": "kinecal.kinematics.serial.joint_errors",
    "solve_ik": "kinecal.kinematics.serial.ik",
})
