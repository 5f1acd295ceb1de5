"""The Stewart-platform (parallel-link) CMM of paper 004 (Liu, Liu & Wei 2008).

Public entry points
-------------------
`StewartPlatform` (`platform`)
    Geometry, inverse kinematics (leg lengths of a pose, paper 004 sec. 2.1, eq. 4-5) and forward
    kinematics: Newton on the analytic Jacobian (`forward`), the paper's PSO (`pso`, eq. 7-9),
    every assembly mode (`modes`); pose parametrisation helpers in `poses`.

The solver modules never import `platform` (they read the few attributes they need), so a
solver can be used without the class.
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "StewartPlatform": "kinecal.kinematics.stewart.platform",
})
