"""Plausibility diagnostics of calibrations: serial arms, Stewart platforms, hand-eye.

Each check is a plain function of arrays and models that calls
`kinecal.diagnostics.warn(code, message)` when it finds something implausible (or raises
`kinecal.InputError` when the data cannot give an answer at all). The calibration entry
points run them; `CODES` lists every code with a one-line meaning (docs/diagnostics.md
explains each one with its likely cause, what to do and an example).
"""

from __future__ import annotations

__all__ = ["CODES"]

#: every diagnostic code kinecal issues -> what it means (a test checks that each code
#: raised in the sources is listed here and documented in docs/diagnostics.md)
CODES: dict[str, str] = {
    "too-few-poses": "the distinct poses give no more equations than free parameters (error)",
    "few-poses": "fewer than 3 equations per free parameter",
    "duplicate-poses": "rows repeat the joint readings of other rows",
    "joint-limits": "joint readings outside the model's joint limits",
    "joint-units": "joint readings look like the other angle unit",
    "scale-mismatch": "measured lengths in another unit than the model's",
    "mirrored-frame": "measured positions fit the model mirrored (an axis negated)",
    "initial-error": "the data are far from the nominal model: wrong model or frame",
    "validation-overlap": "validation poses repeat calibration poses",
    "outside-calibrated-range": "joint readings beyond the joint range the calibration saw",
    "validation-frame": "validation data in another frame (a moved tracker): re-register them",
    "tool-orientation": "measured orientations far from the model's tool frame (stations)",
    "rank-deficient": "the poses identify fewer parameters than well-spread poses do",
    "unidentifiable-free": "free parameters that the poses cannot identify",
    "parameter-tolerance": "an identified parameter moved far beyond its tolerance",
    "residual-offset": "the residual holds an offset a free base frame would take",
    "lack-of-fit": "the residual is far above the repeatability of repeated poses",
    "residual-above-noise": "the residual is far above the instrument's stated noise (--sigma)",
    "residual-below-noise": "the residual is far below the instrument's stated noise (--sigma)",
    "outliers": "poses whose error is far outside the others' spread",
    "optimizer-stalled": "a metaheuristic stopped far above what a least-squares polish reaches",
    "implausible-change": "the calibrated arm is not a calibration of the same arm (fk, export "
                          "and compensate refuse it)",
    "at-bounds": "a metaheuristic's answer sits on a face of the box it searched",
    # measurement kinds: ballbar and pair distances, fixed points, planes
    "pivot-moved": "a ballbar's distances fit no single pivot to the noise",
    "point-spread": "a fixed point's touches disagree by more than the noise",
    "plane-not-flat": "a plane's touches are not flat to the noise",
    "noise-estimate": "the noise of several measurement sets did not settle (they contradict)",
    "leg-range": "Stewart leg readings outside the geometry's leg range",
    "angle-units": "Stewart pose angles or hand-eye pose-file angles that look like radians",
    "handeye-conditioning": "hand-eye motions too close to one rotation axis for the noise",
    "handeye-one-axis": "robot rotations about one axis only (SCARA) and no height given: X's "
                        "translation along it assumed",
    "handeye-height-unused": "a SCARA height given for stations that turn about several axes",
    "handeye-inconsistent": "robot and target poses that fit no X (inverted, quaternion order, "
    "angle unit, --setup)",
    "absolute-errors": "simulate(errors=...) got absolute parameter values, not deviations",
    # hand-eye calibration from images
    "board-symmetric": "a board that looks the same turned (180 deg, or 90 deg for square "
                       "circle grids): frames can flip",
    "board-turned": "images of a symmetric board turned back to fit the robot poses",
    "intrinsics-size": "intrinsics made for another image size than the images'",
    "intrinsics-rms": "the camera calibration from the images leaves more than 1 px RMS",
    "intrinsics-weak": "the views leave the intrinsics estimated from them poorly determined",
    "pnp-rms": "the board poses fit the detected corners poorly (wrong intrinsics or board)",
    "images-rejected": "more than half of the images rejected",
    "reprojection-rms": "the hand-eye solution reprojects the corners poorly",
    "many-outliers": "more than 30 % of the hand-eye stations flagged as outliers",
    # arm calibration from images
    "station-skipped": "stations whose board was not found or not trusted, left out",
    "board-scale": "identified lengths uniformly off nominal: the --board size is wrong",
    # compensation
    "no-seed-joints": "targets without seed joints: inverse kinematics chose the configuration",
    "target-units": "Cartesian targets outside the arm's reach that fit it in another unit",
    "joints-outside-limits": "program or seed joints outside the model's joint limits",
    "base-frame-far": "the calibrated base frame is far from the nominal one",
    "tool-point-far": "the calibrated tool point is far from the nominal one (a target?)",
    "compensation-not-converged": "rows whose compensated joints did not converge",
    "nominal-ik-not-converged": "targets out of reach of the nominal model",
    "near-singular": "rows close to a singularity: large, sensitive joint corrections",
    # readers and export
    "no-marker-column": "a model with several markers, a measurement file without marker column",
    "urdf-joint-limits": "a URDF revolute joint without usable limits",
    "joint-errors-not-exported": "joint-error terms left out of a URDF export (geometry only)",
    "camera-mount-far": "a hand-eye camera exported more than 10 m from its parent frame",
    "ur-conf-implausible": ("UR calibration.conf deltas moving the flange more than a "
                            "factory calibration does"),
    "ur-kinematics-not-ur": ("an ur-kinematics export of a model that is no calibration "
                             "of its UR type"),
    "ros-dwell-moving": "bag dwells dropped: the measurement moved while the joints read still",
    "ros-joint-units": "bag JointState revolute positions beyond two turns (degrees?)",
    "ros-samples-skipped": "JointState messages of a bag left out (positions not matching the "
                           "names, not finite, time not increasing)",
    "ros-bad-values": "bag measurement messages whose values are no measurement (NaN, unset "
                      "quaternion) left out",
    "check-base-moved": "kinecal check: today's change is mostly a move of the base frame",
}
