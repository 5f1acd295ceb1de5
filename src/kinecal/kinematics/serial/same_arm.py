"""Is a calibrated model a calibration of the nominal arm? The one rule every command uses.

Compared through the kinematics, not the parameter lists: the same joints (count and
kind), and tool poses that agree over the workspace once the calibrated model is
registered onto the nominal one by the rigid transform that fits them best. That works
across conventions (a D-H nominal model and its calibrated URDF export), with extra fixed
frames and with joint-error terms, and it separates what a calibration changes (a few
millimetres and tenths of a degree over the workspace) from another arm (more than 15 %
of its size).

`compare_arms` is the rule. The calibration warns ``implausible-change`` when its own
result breaks it (`kinecal.calibration.diagnostics.change`); ``fk --params``, ``export``,
``compensate`` and `kinecal.load_result` refuse such a result (`check_same_arm`). One
function decides both, so a calibration that passed is never refused later, and one that
is refused later was warned about when it was made.

A model with several markers is compared up to its flange: each marker's point is where a
reflector happens to sit, not a part of the arm.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.ik import characteristic_length
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import rotation_angle, transform_from

__all__ = [
    "LENGTH_UNITS",
    "SAME_ARM_ANGLE",
    "SAME_ARM_LENGTH",
    "SAMPLES",
    "ArmComparison",
    "Registration",
    "check_same_arm",
    "compare_arms",
    "flange_model",
    "in_length_unit",
    "register",
]

Array = NDArray[np.float64]

#: largest tool-point distance after registration (fraction of the nominal arm's
#: characteristic length, the sum of its link lengths) and tool-frame angle (rad) of a
#: calibration of the same arm: the tutorial's IRB-120, whose true errors come from paper
#: 002's wide tolerance box (up to 2.9 deg per angle), is off by up to 5 %; real arms by
#: well under 1 %
SAME_ARM_LENGTH = 0.15
SAME_ARM_ANGLE = 0.35
#: configurations compared (fixed seed: the check is deterministic)
SAMPLES = 256
#: length units and their size in metres
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}


class Registration:
    """Best rigid fit of the calibrated tool points onto the nominal ones.

    Attributes
    ----------
    transform : ndarray, shape (4, 4)
        ``X`` with ``X T_calibrated(q) ~ T_nominal(q)`` over the workspace.
    position : ndarray, shape (SAMPLES,)
        Tool-point distances after registration (length unit).
    rotation : ndarray, shape (SAMPLES,)
        Tool-frame angles after registration (rad).
    shift, turn : float
        Translation (length unit) and rotation angle (rad) of ``X``.
    """

    def __init__(self, X: Array, position: Array, rotation: Array) -> None:
        self.transform = X
        self.position = position
        self.rotation = rotation
        self.shift = float(np.linalg.norm(X[:3, 3]))
        self.turn = float(rotation_angle(X[:3, :3]))


def _kabsch(P: Array, Q: Array) -> Array:
    """Rigid transform ``X`` (4, 4) minimising ``sum |R p + t - q|^2`` over rows."""
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    H = (P - cp).T @ (Q - cq)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return transform_from(R, cq - R @ cp)


def _on_a_line(P: Array) -> bool:
    """True when the points ``(N, 3)`` lie on a line (or on one point)."""
    sv = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
    return bool(sv[1] <= 1e-6 * sv[0])


def _what(nominal: SerialModel, calibrated: SerialModel) -> str:
    return f"calibrated model {calibrated.name!r} and nominal model {nominal.name!r}"


def register(nominal: SerialModel, calibrated: SerialModel) -> Registration:
    """Register `calibrated` onto `nominal` over `SAMPLES` workspace configurations (in
    the nominal model's length unit; tool frames as the models give them).

    Raises
    ------
    InputError
        Different joints (count or kind).
    """
    if tuple(calibrated.joint_kinds) != tuple(nominal.joint_kinds):
        raise InputError(f"{_what(nominal, calibrated)} have different joints "
                         f"({calibrated.n_joints} {'/'.join(calibrated.joint_kinds)} vs "
                         f"{nominal.n_joints} {'/'.join(nominal.joint_kinds)}): not the "
                         "same arm")
    calibrated = in_length_unit(calibrated, nominal.length_unit)
    lim = np.array(nominal.joint_limits, dtype=float)
    rev = ~nominal.is_prismatic()
    lim[rev] = np.clip(lim[rev], -np.pi, np.pi)
    q = np.random.default_rng(0).uniform(lim[:, 0], lim[:, 1], (SAMPLES, nominal.n_joints))
    Tn, Tc = nominal.fk(q), calibrated.fk(q)
    P, Q = Tc[:, :3, 3], Tn[:, :3, 3]
    if _on_a_line(P) or _on_a_line(Q):
        # tool points on a line (an arm of parallel prismatic axes, a tool point on every
        # joint axis) leave the turn about that line free: the tool frames' axes fix it
        L = characteristic_length(nominal)
        P = np.vstack([P + L * Tc[:, :3, k] for k in range(3)] + [P])
        Q = np.vstack([Q + L * Tn[:, :3, k] for k in range(3)] + [Q])
    X = _kabsch(P, Q)
    Tr = X @ Tc
    pos = np.linalg.norm(Tr[:, :3, 3] - Tn[:, :3, 3], axis=1)
    rot = rotation_angle(np.swapaxes(Tn[:, :3, :3], 1, 2) @ Tr[:, :3, :3])
    return Registration(X, pos, rot)


@dataclass(frozen=True)
class ArmComparison:
    """What `compare_arms` found.

    Attributes
    ----------
    registration : Registration
        The best rigid fit (of the flanges when the models have several markers).
    length, angle : float
        Largest tool-point distance (length unit) and tool-frame angle (rad) after it.
    length_limit, angle_limit : float
        What a calibration of the same arm stays within (`SAME_ARM_LENGTH` of the nominal
        arm's characteristic length, `SAME_ARM_ANGLE`).
    finding : str or None
        What differs and by how much, or None for a calibration of the same arm.
    """

    registration: Registration
    length: float
    angle: float
    length_limit: float
    angle_limit: float
    finding: str | None

    @property
    def same(self) -> bool:
        """True for a calibration of the same arm."""
        return self.finding is None


def flange_model(model: SerialModel) -> SerialModel:
    """`model` up to its flange when it has several markers (their points are where
    reflectors sit, not the arm; the joint-error terms go too, their reference geometry
    names the markers); otherwise `model` itself."""
    if not model.marker_names:
        return model
    return dataclasses.replace(
        model, markers=None, tool=None, joint_errors=None,
        joint_limits=np.array(model.joint_limits), tolerances=dict(model.tolerances or {}),
        fixed=tuple(f for f in model.fixed if not f.startswith("tool.")))


def compare_arms(nominal: SerialModel, calibrated: SerialModel) -> ArmComparison:
    """The same-arm rule (module docstring): same joints, and after the best rigid
    registration every tool point within `SAME_ARM_LENGTH` of the nominal arm's
    characteristic length and every tool frame within `SAME_ARM_ANGLE` rad, over `SAMPLES`
    configurations within the joint limits (the flanges for models with markers).

    Raises
    ------
    InputError
        Different joints (count or kind), or lengths that cannot be converted.
    """
    nom, cal = flange_model(nominal), flange_model(calibrated)
    reg = register(nom, cal)
    what = _what(nominal, calibrated)
    L = characteristic_length(nom)
    d, a = float(reg.position.max()), float(reg.rotation.max())
    lim_d, lim_a = SAME_ARM_LENGTH * L, SAME_ARM_ANGLE
    unit = nominal.length_unit
    finding = None
    part = "flanges" if nominal.marker_names or calibrated.marker_names else "tool points"
    if not np.isfinite(d) or d > lim_d:
        finding = (f"{what}: their {part} differ by up to {d:.4g} {unit} over the "
                   f"workspace (a calibration moves them by less than {lim_d:.3g} {unit})"
                   ": not a calibration of the same arm")
    elif not np.isfinite(a) or a > lim_a:
        frames = "flange" if part == "flanges" else "tool"
        finding = (f"{what}: their {frames} frames differ by up to {np.degrees(a):.3g} deg "
                   f"over the workspace (a calibration turns them by less than "
                   f"{np.degrees(lim_a):.3g} deg): not a calibration of the same arm")
    return ArmComparison(reg, d, a, lim_d, lim_a, finding)


def check_same_arm(nominal: SerialModel, calibrated: SerialModel) -> Registration:
    """Refuse a calibrated model of another arm than `nominal` (`compare_arms`); returns
    the registration.

    Raises
    ------
    InputError
        Naming what differs and by how much.
    """
    found = compare_arms(nominal, calibrated)
    if found.finding is not None:
        raise InputError(found.finding)
    return found.registration


def in_length_unit(model: SerialModel, unit: str) -> SerialModel:
    """`model` with every length (chain, base, tool, prismatic joint limits, the length
    tolerance) expressed in `unit` (``"mm"`` or ``"m"``); angles unchanged.

    Raises
    ------
    InputError
        Unknown unit, or a model with joint-error terms (their coefficients carry their own
        units: convert the model file instead).
    """
    if model.length_unit == unit:
        return model
    if unit not in LENGTH_UNITS or model.length_unit not in LENGTH_UNITS:
        raise InputError(f"cannot convert lengths from {model.length_unit!r} to {unit!r}")
    if model.joint_errors is not None:
        raise InputError(f"model {model.name!r} is in {model.length_unit} and has joint-error "
                         f"terms: give it in {unit}, like the nominal model")
    f = LENGTH_UNITS[model.length_unit] / LENGTH_UNITS[unit]
    p = model.nominal
    p[~model.is_angle()] *= f
    scaled = model.with_params(p)
    limits = np.array(model.joint_limits, dtype=float)
    limits[model.is_prismatic()] *= f
    tol = dict(model.tolerances or {})
    if "length" in tol:
        tol["length"] = tol["length"] * f
    return dataclasses.replace(scaled, length_unit=unit, joint_limits=limits, tolerances=tol)
