"""One calibration problem from several measurement kinds: residual blocks over shared
parameter blocks (industrial_calibration's and Ceres' model; DESIGN section 7).

A serial arm is identified at once from any mix of: tracker points or poses, ballbar
distances from unknown pivots, known distances between pairs of tool points (an artifact
bar), touches of unknown fixed points (sphere sockets), touches of unknown planes (a touch
probe); other kinds (a camera's pixels) plug in as further blocks. Papers: the arm's
kinematics and identification Jacobian as in `kinecal.calibration.serial` (papers 000,
002); variance components per measurement kind after Foerstner (1979); ballbar tests of
robots as in ISO 230-4 practice, fixed-point and plane constraints as in the
robot_calibration / FIGAROH literature.

How to add a measurement kind
-----------------------------
Subclass `ResidualBlock` (`base`; its docstring lists the interface: ``kind``, ``unit``,
``blind_to``, ``obs_dof``, ``n_obs`` / ``obs_index``, ``nuisance_names``, ``start``,
``evaluate`` with the analytic Jacobian for the arm columns asked for (through
`SerialModel`'s identification Jacobian, `base.tool_points`, or
``model.identification_jacobian(q, p, "pose")`` for a block that sees the tool frame) and
for its own unknowns, ``observation_errors``, the ``check_data`` / ``check_fit`` hooks and
``nuisance_report``), check its Jacobian against central differences in a test (as
``tests/calibration/test_blocks.py`` does for every kind), and pass instances to
`calibrate_blocks` (or `kinecal.calibrate` with a list). Nothing else changes: the stack
(`stack`), the identifiability with the nuisance marginalised (`analysis`) and the blind
motions named (`motions`), the noise per block (`weights`), the fit (`solve`), the
uncertainty (`uncertainty`) and the result (`result`) are shared. A block without unknowns
of its own may accumulate its normal equations itself (``arm_normal``, as the tracker rows
do chunk by chunk and chain by chain) instead of handing the stack dense rows.

Public entry points
-------------------
`calibrate_blocks` (`api`)
    ``calibrate_blocks(model, [data, ...], sigma=[...], validate=[...])`` ->
    `KindsCalibrationResult` (`result`), a `CalibrationResult` (JSON, report, model file).
`ResidualBlock`, `BlockRows`, `tool_points` (`base`)
    The block interface.
`TrackerBlock`, `BallbarBlock`, `PairBlock`, `PointBlock`, `PlaneBlock`
    The kinds (one module each); `make_blocks` (`make`) builds them from data.
`StackedProblem` (`stack`), `analyse_stack` (`analysis`)
    The stacked least-squares problem and its identifiability.
`simulate_kind` (`simulate`)
    Synthetic measurements of each kind from a perturbed arm.
"""

from kinecal._lazy import lazy_exports

__getattr__, __dir__ = lazy_exports(__name__, {
    "calibrate_blocks": "kinecal.calibration.blocks.api",
    "KindsCalibrationResult": "kinecal.calibration.blocks.result",
    "ResidualBlock": "kinecal.calibration.blocks.base",
    "BlockRows": "kinecal.calibration.blocks.base",
    "tool_points": "kinecal.calibration.blocks.base",
    "TrackerBlock": "kinecal.calibration.blocks.tracker",
    "BallbarBlock": "kinecal.calibration.blocks.ballbar",
    "PairBlock": "kinecal.calibration.blocks.pair",
    "PointBlock": "kinecal.calibration.blocks.point",
    "PlaneBlock": "kinecal.calibration.blocks.plane",
    "make_blocks": "kinecal.calibration.blocks.make",
    "StackedProblem": "kinecal.calibration.blocks.stack",
    "analyse_stack": "kinecal.calibration.blocks.analysis",
    "simulate_kind": "kinecal.calibration.blocks.simulate",
})
