"""Serial-arm kinematic model `SerialModel`: chain of elementary motions, parameter vector.

Every geometric parameter enters the chain as one *elementary motion*: a rotation about,
or a translation along, one axis of the moving frame (`kinecal.kinematics.serial.motions`). A
convention lists a joint's elementary motions in order (see ``docs/conventions.md``):

* `dh_motions` (standard D-H, paper 000 eq. 1): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)``
* `craig_motions` (modified / proximal D-H): ``Rx(alpha) Tx(a) Rz(theta + q) Tz(d)``
* `hayati_motions` (paper 002): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha) Ry(beta)``
* `urdf_motions`: ``Tx(x) Ty(y) Tz(z) Rz(yaw) Ry(pitch) Rx(roll)``, the origin's local
  rotation error ``Rz(wz) Ry(wy) Rx(wx)`` (the nominal rpy held), then the motion about
  or along the joint's unit axis by ``offset + q``

Prismatic joints add their reading to a translation (``d`` in the D-H family); fixed
frames anywhere in the chain are six more motions (`kinecal.kinematics.serial.chain`).
The base frame is ``Tx(x) Ty(y) Tz(z)``, its nominal roll-pitch-yaw held, then the local
rotation error ``Rz(rz) Ry(ry) Rx(rx)`` (``base.rx .. base.rz``, zero nominally); the tool
``Tx(x) Ty(y) Tz(z)``, for a tool frame followed likewise by its nominal orientation and
local error (`kinecal.kinematics.serial.motions.local_pose_motions`).

Forward kinematics and the identification and joint Jacobians are the methods of
`kinecal.kinematics.serial.kinematics.SerialKinematics`, which `SerialModel` inherits; this
module holds the model itself: its chain, parameter vector, units and limits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.chain import (
    BASE_NAMES,
    TOOL_NAMES,
    Chain,
    build_chain,
    chain_entries,
    frame_list,
)
from kinecal.kinematics.serial.kinematics import SerialKinematics
from kinecal.kinematics.serial.markers import (
    MarkerSet,
    marker_parameter_names,
    marker_points,
    with_markers,
)
from kinecal.kinematics.serial.motions import (
    CONVENTIONS,
    PRISMATIC,
    ROTATION,
    Motion,
    craig_motions,
    dh_motions,
    hayati_motions,
    urdf_motions,
)
from kinecal.kinematics.serial.parameters import ParameterVector
from kinecal.kinematics.serial.sweep import Sweep

if TYPE_CHECKING:  # loaded with a model's joint errors only
    from kinecal.kinematics.serial.joint_errors import JointErrors

__all__ = [
    "BASE_NAMES",
    "CONVENTIONS",
    "TOOL_NAMES",
    "Motion",
    "SerialModel",
    "Sweep",
    "craig_motions",
    "dh_motions",
    "hayati_motions",
    "urdf_motions",
]

Array = NDArray[np.float64]


@dataclass(repr=False)
class SerialModel(SerialKinematics, ParameterVector):
    """Kinematic model of a serial arm: revolute and prismatic joints, fixed frames.

    Parameters
    ----------
    name : str
        Model name.
    convention : {"dh", "craig", "hayati", "urdf"}
        Joint convention (see module docstring).
    joints : sequence of dict
        The chain from base to flange, one dict per entry (`kinecal.kinematics.serial.chain`):
        a moving joint (``theta, d, a, alpha`` and ``beta`` for hayati joints that use it;
        urdf: ``name, x, y, z, roll, pitch, yaw, offset, axis``), with ``type:
        prismatic`` for a prismatic joint (urdf also ``continuous``); or a fixed frame
        ``{frame: NAME, x, y, z, rx, ry, rz}`` (urdf: roll, pitch, yaw), held at nominal
        unless it says ``calibrate: True``. Lengths in `length_unit`, angles in radians.
    base : array_like, shape (6,) or (9,), optional
        Base frame in the measurement frame: x, y, z (length unit), rx, ry, rz (rad),
        ``R = Rz Ry Rx``, and optionally the local rotation error wx, wy, wz after it (a
        calibrated model; ``R = Rz(rz) Ry(ry) Rx(rx) Rz(wz) Ry(wy) Rx(wx)``). The
        parameters ``base.x .. base.z`` are the origin, ``base.rx .. base.rz`` the local
        error (`kinecal.kinematics.serial.chain`). Absent: the measurements are in the
        robot base frame and the six base parameters are fixed at zero.
    tool : array_like, shape (3,), (6,) or (9,), optional
        Tool point (x, y, z) in the flange frame, or a tool frame (x, y, z, rx, ry, rz
        [, wx, wy, wz]) parametrised as the base. Absent: the flange origin, tool
        parameters fixed at zero.
    length_unit : str
        ``"mm"`` or ``"m"``; informative, every length uses it.
    angle_unit : {"rad", "deg"}
        Unit of angles in this model's files (model file, revolute joint columns of
        measurement CSVs; prismatic columns are in the length unit). The Python API always
        uses radians.
    joint_limits : array_like, shape (n_joints, 2), optional
        Joint ranges, rad for revolute and length unit for prismatic joints (default
        ``[-pi, pi]`` for revolute joints; prismatic joints need limits).
    tolerances : dict, optional
        ``{"length": L, "angle": A}``: half-width of the metaheuristics' search box around
        nominal (length unit, rad). Default 1 length unit and 0.02 rad.
    fixed : sequence of str, optional
        Parameters held at nominal unless explicitly freed (by the model's design).
    joint_errors : JointErrors, optional
        Non-geometric joint-angle corrections (`kinecal.kinematics.serial.joint_errors`); their
        coefficients are appended to the parameter vector, after base and tool.
    markers : mapping of str to (3,), optional
        Several tool points, one per marker (flange frame, length unit), instead of `tool`:
        parameters ``tool.NAME.x .. z``; the kinematics take a per-pose marker index
        (`kinecal.kinematics.serial.markers`).
    """

    name: str
    convention: str
    joints: Sequence[dict]
    base: ArrayLike | None = None
    tool: ArrayLike | None = None
    length_unit: str = "mm"
    angle_unit: str = "rad"
    joint_limits: ArrayLike | None = None
    tolerances: dict | None = None
    fixed: Sequence[str] = ()
    description: str = ""
    joint_errors: JointErrors | None = None
    markers: dict | None = None
    motions: list[Motion] = field(init=False, repr=False)

    def __repr__(self) -> str:
        extra = f", markers {', '.join(self.marker_names)}" if self.marker_names else ""
        if self.joint_errors is not None:
            extra += ", joint errors"
        return (f"<SerialModel {self.name} ({self.convention}): {self.n_joints} joints, "
                f"{self.n_params} parameters, {self.length_unit}/{self.angle_unit}{extra}>")

    def __post_init__(self) -> None:
        if self.angle_unit not in ("rad", "deg"):
            raise InputError(f"angle_unit: expected rad or deg, got {self.angle_unit!r}")
        chain = build_chain(self.convention, self.joints, self.base, self.tool, self.markers)
        self._chain: Chain = chain
        self.motions = list(chain.motions)
        self._names = chain.names
        self._index = {n: k for k, n in enumerate(self._names)}
        self._nominal = np.array([chain.values[n] for n in self._names])
        # parameter of each motion; -1 for a constant (a frame's nominal orientation)
        self._motion_index = np.array([-1 if m.const is not None else self._index[m.name]
                                       for m in self.motions], dtype=np.intp)
        # parameter carrying each joint's reading (the motion whose value adds q_j)
        joint_param = {m.joint: self._index[m.name] for m in self.motions
                       if m.joint is not None}
        self._joint_columns = np.array([joint_param[j] for j in range(len(chain.kinds))],
                                       dtype=np.intp)
        self._rotation_mask = np.array([m.kind == ROTATION for m in self.motions])
        self._angle_mask = np.zeros(len(self._names), dtype=bool)
        rotated = self._motion_index[self._rotation_mask]
        self._angle_mask[rotated[rotated >= 0]] = True
        self._n_geometric = len(self._names)
        self._joint_terms: JointErrorTerms | None = None
        if self.joint_errors is not None:  # coefficients appended after base and tool
            # imported here: a model without joint errors (most) never loads their terms
            from kinecal.kinematics.serial.joint_errors import JointErrorTerms

            terms = self._joint_terms = JointErrorTerms(self, self.joint_errors)
            self._names = self._names + terms.names
            self._index = {n: k for k, n in enumerate(self._names)}
            self._nominal = np.r_[self._nominal, terms.nominal]
            self._angle_mask = np.r_[self._angle_mask, terms.is_angle()]
        fixed = set(self.fixed) | chain.frozen
        if self.base is None:
            fixed |= set(BASE_NAMES)
        if self.tool is None and not chain.markers:
            fixed |= set(TOOL_NAMES[:3])
        self._marker_set = None
        if chain.markers:
            self._marker_set = MarkerSet(
                chain.markers,
                np.array([self.index(marker_parameter_names(n)) for n in chain.markers]),
                tuple(len(self.motions) - 3 + c for c in range(3)))
        unknown = fixed - set(self._names)
        if unknown:
            raise InputError(f"fixed: unknown parameter(s) {sorted(unknown)}")
        self._fixed = frozenset(fixed)
        n = self.n_joints
        prismatic = self.is_prismatic()
        if self.joint_limits is None:
            if prismatic.any():
                raise InputError(f"joint_limits: prismatic joint(s) "
                                 f"{(np.flatnonzero(prismatic) + 1).tolist()} need limits "
                                 f"(length unit)")
            self.joint_limits = np.tile([-np.pi, np.pi], (n, 1))
        self.joint_limits = np.asarray(self.joint_limits, dtype=float)
        lim = self.joint_limits
        if lim.shape != (n, 2) or not np.isfinite(lim).all() or (lim[:, 0] >= lim[:, 1]).any():
            raise InputError(f"joint_limits: expected {n} pairs [low, high] with low < high")
        self.tolerances = {"length": 1.0, "angle": 0.02, **(self.tolerances or {})}

    # ------------------------------------------------------------------ parameters
    @property
    def n_joints(self) -> int:
        """Number of moving joints (fixed frames not counted)."""
        return len(self._chain.kinds)

    @property
    def chain(self) -> Chain:
        """The chain's motions, their owners (entry index, ``"base"``, ``"tool"``), parameter
        names and nominal values (`kinecal.kinematics.serial.chain.Chain`)."""
        return self._chain

    @property
    def marker_names(self) -> tuple[str, ...]:
        """Names of the markers (several tool points), empty for a single tool point."""
        return self._chain.markers

    def with_markers(self, markers) -> SerialModel:
        """This model with several markers instead of one tool point: `markers` is
        ``{name: [x, y, z]}`` or names, each then starting at the model's tool point."""
        return with_markers(self, markers)

    @property
    def joint_kinds(self) -> tuple[str, ...]:
        """``"revolute"`` or ``"prismatic"`` per joint."""
        return self._chain.kinds

    def is_prismatic(self) -> NDArray[np.bool_]:
        """Mask ``(n_joints,)``: True for prismatic joints (readings in the length unit)."""
        return np.array([k == PRISMATIC for k in self._chain.kinds])

    def joint_scale(self, angle_unit: str | None = None) -> Array:
        """Factor per joint column from file units to the API's units ``(n_joints,)``.

        ``q_api = q_file * joint_scale()``: ``pi / 180`` for a revolute joint when the
        angle unit (default: the model's) is ``deg``, 1 for ``rad`` and for prismatic
        joints (length unit in files and API alike). Every reader and writer of joint
        columns, and joint limits in model files, use it.
        """
        unit = self.angle_unit if angle_unit is None else angle_unit
        if unit not in ("deg", "rad"):
            raise InputError(f"angle unit: expected deg or rad, got {unit!r}")
        rev = np.pi / 180.0 if unit == "deg" else 1.0
        return np.where(self.is_prismatic(), 1.0, rev)

    def index(self, names: Sequence[str]) -> NDArray[np.intp]:
        """Indices of `names` in the parameter vector; unknown names raise `InputError`."""
        missing = [n for n in names if n not in self._index]
        if missing:
            raise InputError(
                f"unknown parameter(s) {missing}; model {self.name!r} has {', '.join(self._names)}"
            )
        return np.array([self._index[n] for n in names], dtype=np.intp)

    def is_angle(self) -> NDArray[np.bool_]:
        """Mask ``(n_params,)``: True where the parameter is an angle (rad), i.e. the value
        of a rotation (``theta, alpha, beta, rx .. rz, roll .. yaw``, a revolute urdf
        joint's ``offset``)."""
        return self._angle_mask.copy()

    def with_params(self, params: ArrayLike, name: str | None = None) -> SerialModel:
        """A copy of the model whose nominal values are `params` ``(n_params,)``."""
        p = self._check_params(params)
        if p.ndim != 1:
            raise InputError("with_params expects one parameter vector")
        values = dict(zip(self._names, p.tolist(), strict=True))
        joints = chain_entries(self._chain, self.joints, values)
        base = frame_list([values[n] for n in BASE_NAMES], self._chain.base_rpy)
        if self.base is None and not any(base):
            base = None
        n_tool = 3 if self.tool is None else np.asarray(self.tool).size
        markers = marker_points(self.marker_names, values) if self.marker_names else None
        tool = None if markers else (
            [values[n] for n in TOOL_NAMES[:3]] if n_tool == 3 else
            frame_list([values[n] for n in TOOL_NAMES], self._chain.tool_rpy))
        if self.tool is None and not any(tool or ()):
            tool = None
        # Keep what was fixed by the model's design, including frames that were absent
        # (fixed frames' own defaults come back with their entries).
        fixed = tuple(n for n in self._names if n in self._fixed and n not in self._chain.frozen)
        je = self._joint_terms
        if je is not None:
            je = self.joint_errors.with_values(
                dict(zip(je.names, p[self._n_geometric:].tolist(), strict=True)), je.reference)
        return SerialModel(
            name=name or self.name, convention=self.convention, joints=joints, base=base,
            tool=tool, length_unit=self.length_unit, angle_unit=self.angle_unit,
            joint_limits=self.joint_limits,
            tolerances=dict(self.tolerances or {}), fixed=fixed,
            description=self.description, joint_errors=je, markers=markers,
        )

