"""Robot systems: several serial chains from one root that share links, joints and
parameters (a torso with two arms, two arms on one base, a robot on a rail beside a
positioner), with coupled (mimic) joints.

Nothing new is computed here: each chain is a serial chain of elementary motions
(`kinecal.kinematics.serial`, papers 000 and 002) whose parameters are columns of the
system's parameter vector, so the forward kinematics and the analytic identification
Jacobian of a row are its chain's, and chains through a shared element write the same
columns. See docs/systems.md.

Public entry points
-------------------
`SystemModel` (`system`)
    The system: its tips, joints and parameters; per-row forward kinematics and Jacobians
    (`forward`); `SystemModel.link_poses` / `link_sweep` / `link_points` (any link's pose
    and its Jacobian per row); `SystemModel.tip_model` (one chain as a `SerialModel`).
`Element`, `Tip`, `Mimic` (`elements`)
    What a system is built from (the readers in `kinecal.io` make them from a URDF tree or
    a ``kind: system`` file).
`is_system`
    Whether a model is a system.
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "SystemModel": "kinecal.kinematics.tree.system",
    "is_system": "kinecal.kinematics.tree.system",
    "Element": "kinecal.kinematics.tree.elements",
    "Tip": "kinecal.kinematics.tree.elements",
    "Mimic": "kinecal.kinematics.tree.elements",
})
