"""Serial-arm kinematics: `SerialModel`, batch forward kinematics, identification Jacobian.

Every geometric parameter enters the chain as one *elementary motion*: a rotation about,
or a translation along, one axis of the moving frame. A convention is therefore a
function that lists a joint's elementary motions in order (see ``docs/conventions.md``):

* `dh_motions` (standard D-H, paper 000 eq. 1): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)``
* `craig_motions` (modified / proximal D-H): ``Rx(alpha) Tx(a) Rz(theta + q) Tz(d)``
* `hayati_motions` (paper 002): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha) Ry(beta)``

The base frame is ``Tx(x) Ty(y) Tz(z) Rz(rz) Ry(ry) Rx(rx)`` (a pose in roll-pitch-yaw),
the tool ``Tx(x) Ty(y) Tz(z)`` followed by ``Rz Ry Rx`` for a tool frame.

Forward kinematics composes the motions on axis-vector stacks of shape
``(3, P, N)`` (component, population, poses), without Python loops over poses or
parameter vectors. The identification Jacobian follows from the same sweep: a rotation
about a unit axis ``u`` through ``o`` moves the tool point ``p`` by ``u x (p - o)`` per
radian, a translation along ``u`` moves it by ``u``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError

__all__ = [
    "CONVENTIONS",
    "Motion",
    "SerialModel",
    "Sweep",
    "craig_motions",
    "dh_motions",
    "hayati_motions",
]

Array = NDArray[np.float64]

ROTATION, TRANSLATION = "R", "T"
X, Y, Z = 0, 1, 2


@dataclass(frozen=True)
class Motion:
    """One elementary motion of the chain.

    Attributes
    ----------
    kind : {"R", "T"}
        Rotation about, or translation along, a local axis.
    axis : int
        0, 1, 2 for the x, y, z axis of the moving frame.
    name : str
        Parameter name (``theta1``, ``base.x``, ...).
    joint : int or None
        0-based joint index whose reading ``q`` adds to the angle (only for ``theta``).
    """

    kind: str
    axis: int
    name: str
    joint: int | None = None


def dh_motions(i: int, with_beta: bool = False) -> list[Motion]:
    """Standard D-H joint ``i`` (1-based): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha)``.

    Paper 000 eq. (1) writes ``Rotate(Z, theta) Transfer(0, 0, h) Transfer(d, 0, 0)
    Rotate(X, alpha)``: its (d, h) are our (a, d).
    """
    if with_beta:
        raise InputError(f"joint {i}: beta is only defined for the hayati convention")
    return [
        Motion(ROTATION, Z, f"theta{i}", i - 1),
        Motion(TRANSLATION, Z, f"d{i}"),
        Motion(TRANSLATION, X, f"a{i}"),
        Motion(ROTATION, X, f"alpha{i}"),
    ]


def craig_motions(i: int, with_beta: bool = False) -> list[Motion]:
    """Modified (proximal, Craig) D-H joint ``i``: ``Rx(alpha) Tx(a) Rz(theta + q) Tz(d)``."""
    if with_beta:
        raise InputError(f"joint {i}: beta is only defined for the hayati convention")
    return [
        Motion(ROTATION, X, f"alpha{i}"),
        Motion(TRANSLATION, X, f"a{i}"),
        Motion(ROTATION, Z, f"theta{i}", i - 1),
        Motion(TRANSLATION, Z, f"d{i}"),
    ]


def hayati_motions(i: int, with_beta: bool = False) -> list[Motion]:
    """Hayati joint ``i`` (paper 002): ``Rz(theta + q) Tz(d) Tx(a) Rx(alpha) [Ry(beta)]``.

    ``beta`` is present only on joints that declare it (nearly parallel consecutive axes).
    """
    motions = [
        Motion(ROTATION, Z, f"theta{i}", i - 1),
        Motion(TRANSLATION, Z, f"d{i}"),
        Motion(TRANSLATION, X, f"a{i}"),
        Motion(ROTATION, X, f"alpha{i}"),
    ]
    if with_beta:
        motions.append(Motion(ROTATION, Y, f"beta{i}"))
    return motions


CONVENTIONS: dict[str, Callable[[int, bool], list[Motion]]] = {
    "dh": dh_motions,
    "craig": craig_motions,
    "hayati": hayati_motions,
}

BASE_NAMES = ("base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz")
TOOL_NAMES = ("tool.x", "tool.y", "tool.z", "tool.rx", "tool.ry", "tool.rz")


def _base_motions() -> list[Motion]:
    return [
        Motion(TRANSLATION, X, "base.x"),
        Motion(TRANSLATION, Y, "base.y"),
        Motion(TRANSLATION, Z, "base.z"),
        Motion(ROTATION, Z, "base.rz"),
        Motion(ROTATION, Y, "base.ry"),
        Motion(ROTATION, X, "base.rx"),
    ]


def _tool_motions(frame: bool) -> list[Motion]:
    motions = [
        Motion(TRANSLATION, X, "tool.x"),
        Motion(TRANSLATION, Y, "tool.y"),
        Motion(TRANSLATION, Z, "tool.z"),
    ]
    if frame:
        motions += [
            Motion(ROTATION, Z, "tool.rz"),
            Motion(ROTATION, Y, "tool.ry"),
            Motion(ROTATION, X, "tool.rx"),
        ]
    return motions


@dataclass
class SerialModel:
    """Kinematic model of a serial arm with revolute joints.

    Parameters
    ----------
    name : str
        Model name.
    convention : {"dh", "craig", "hayati"}
        Joint convention (see module docstring).
    joints : sequence of dict
        One dict per joint with ``theta, d, a, alpha`` (and ``beta`` for hayati joints that
        use it). Lengths in `length_unit`, angles in radians.
    base : array_like, shape (6,), optional
        Base frame in the measurement frame: x, y, z (length unit), rx, ry, rz (rad),
        ``R = Rz Ry Rx``. Absent: the measurements are in the robot base frame and the six
        base parameters are fixed at zero.
    tool : array_like, shape (3,) or (6,), optional
        Tool point (x, y, z) in the flange frame, or a tool frame (x, y, z, rx, ry, rz).
        Absent: the flange origin, tool parameters fixed at zero.
    length_unit : str
        ``"mm"`` or ``"m"``; informative, every length uses it.
    angle_unit : {"rad", "deg"}
        Unit of angles in this model's files (model file, joint columns of measurement CSVs).
        The Python API always uses radians.
    joint_limits : array_like, shape (n_joints, 2), optional
        Joint ranges in rad (default ``[-pi, pi]`` each).
    tolerances : dict, optional
        ``{"length": L, "angle": A}``: half-width of the metaheuristics' search box around
        nominal (length unit, rad). Default 1 length unit and 0.02 rad.
    fixed : sequence of str, optional
        Parameters held at nominal unless explicitly freed (by the model's design).
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
    motions: list[Motion] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise InputError(
                f"unknown convention {self.convention!r}; expected one of {', '.join(CONVENTIONS)}"
            )
        if len(self.joints) < 1:
            raise InputError("a model needs at least one joint")
        make = CONVENTIONS[self.convention]
        motions: list[Motion] = _base_motions()
        values: dict[str, float] = dict.fromkeys(BASE_NAMES, 0.0)
        if self.base is not None:
            base = np.asarray(self.base, dtype=float)
            if base.shape != (6,):
                raise InputError(f"base: expected 6 values (x, y, z, rx, ry, rz), got {base.size}")
            values.update(zip(BASE_NAMES, base, strict=True))
        for i, joint in enumerate(self.joints, start=1):
            with_beta = "beta" in joint
            jm = make(i, with_beta)
            motions += jm
            for m in jm:
                key = m.name.rstrip("0123456789")
                if key not in joint:
                    raise InputError(f"joint {i}: missing {key!r}")
                values[m.name] = float(joint[key])
        tool = np.zeros(3) if self.tool is None else np.asarray(self.tool, dtype=float)
        if tool.shape not in ((3,), (6,)):
            raise InputError(f"tool: expected 3 (point) or 6 (frame) values, got {tool.size}")
        motions += _tool_motions(tool.shape == (6,))
        values.update(zip(TOOL_NAMES, tool, strict=False))
        self.motions = motions
        # Parameter vector: per joint in motion order, then base, then tool.
        joint_names = [m.name for m in motions if not m.name.startswith(("base.", "tool."))]
        tool_names = [m for m in TOOL_NAMES[: tool.size]]
        self._names = tuple(joint_names + list(BASE_NAMES) + tool_names)
        self._index = {n: k for k, n in enumerate(self._names)}
        self._nominal = np.array([values[n] for n in self._names])
        self._motion_index = np.array([self._index[m.name] for m in motions])
        # parameter carrying each joint's reading (the motion whose value adds q_j)
        joint_param = {m.joint: self._index[m.name] for m in motions if m.joint is not None}
        self._joint_columns = np.array([joint_param[j] for j in range(len(self.joints))],
                                       dtype=np.intp)
        self._rotation_mask = np.array([m.kind == ROTATION for m in motions])
        fixed = set(self.fixed)
        if self.base is None:
            fixed |= set(BASE_NAMES)
        if self.tool is None:
            fixed |= set(TOOL_NAMES[:3])
        unknown = fixed - set(self._names)
        if unknown:
            raise InputError(f"fixed: unknown parameter(s) {sorted(unknown)}")
        self._fixed = frozenset(fixed)
        n = len(self.joints)
        if self.joint_limits is None:
            self.joint_limits = np.tile([-np.pi, np.pi], (n, 1))
        self.joint_limits = np.asarray(self.joint_limits, dtype=float)
        lim = self.joint_limits
        if lim.shape != (n, 2) or (lim[:, 0] >= lim[:, 1]).any():
            raise InputError(f"joint_limits: expected {n} pairs [low, high] with low < high")
        self.tolerances = {"length": 1.0, "angle": 0.02, **(self.tolerances or {})}

    # ------------------------------------------------------------------ parameters
    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return len(self.joints)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of the full parameter vector, in order."""
        return self._names

    @property
    def n_params(self) -> int:
        """Length of the full parameter vector."""
        return len(self._names)

    @property
    def nominal(self) -> Array:
        """Nominal parameter vector ``(n_params,)`` (lengths in the model unit, angles in rad)."""
        return self._nominal.copy()

    @property
    def fixed_names(self) -> frozenset[str]:
        """Parameters fixed by the model's design (not calibrated by default)."""
        return self._fixed

    @property
    def calibratable(self) -> tuple[str, ...]:
        """Parameters calibrated by default (all but the fixed ones), in vector order."""
        return tuple(n for n in self._names if n not in self._fixed)

    def index(self, names: Sequence[str]) -> NDArray[np.intp]:
        """Indices of `names` in the parameter vector; unknown names raise `InputError`."""
        missing = [n for n in names if n not in self._index]
        if missing:
            raise InputError(
                f"unknown parameter(s) {missing}; model {self.name!r} has {', '.join(self._names)}"
            )
        return np.array([self._index[n] for n in names], dtype=np.intp)

    def is_angle(self) -> NDArray[np.bool_]:
        """Mask ``(n_params,)``: True where the parameter is an angle (rad)."""
        return np.array([n.split(".")[-1].rstrip("0123456789") in
                         ("theta", "alpha", "beta", "rx", "ry", "rz") for n in self._names])

    def with_params(self, params: ArrayLike, name: str | None = None) -> SerialModel:
        """A copy of the model whose nominal values are `params` ``(n_params,)``."""
        p = self._check_params(params)
        if p.ndim != 1:
            raise InputError("with_params expects one parameter vector")
        values = dict(zip(self._names, p, strict=True))
        joints = []
        for i, joint in enumerate(self.joints, start=1):
            joints.append({k: values[f"{k}{i}"] for k in joint})
        base = [values[n] for n in BASE_NAMES]
        if self.base is None and not any(base):
            base = None
        n_tool = 3 if self.tool is None else np.asarray(self.tool).size
        tool = [values[n] for n in TOOL_NAMES[:n_tool]]
        if self.tool is None and not any(tool):
            tool = None
        # Keep what was fixed by the model's design, including frames that were absent.
        fixed = tuple(n for n in self._names if n in self._fixed)
        return SerialModel(
            name=name or self.name, convention=self.convention, joints=joints, base=base,
            tool=tool, length_unit=self.length_unit, angle_unit=self.angle_unit,
            joint_limits=self.joint_limits,
            tolerances=dict(self.tolerances or {}), fixed=fixed,
            description=self.description,
        )

    # ------------------------------------------------------------------ kinematics
    def _check_params(self, params: ArrayLike | None) -> Array:
        if params is None:
            return self._nominal
        p = np.asarray(params, dtype=float)
        if p.shape[-1:] != (self.n_params,) or p.ndim > 2:
            raise InputError(
                f"parameters: expected shape ({self.n_params},) or (P, {self.n_params}), "
                f"got {p.shape}"
            )
        return p

    def _check_q(self, q: ArrayLike) -> Array:
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise InputError(
                f"joint values: expected shape (N, {self.n_joints}), got {np.shape(q)}"
            )
        if not np.isfinite(q).all():
            raise InputError("joint values contain NaN or infinite entries")
        return q

    def _sweep(self, q: Array, p: Array, record: bool) -> tuple[Array, Array, list]:
        """Compose all motions on frame stacks.

        The frame is kept as three axis arrays and an origin, each ``(3, *batch, N)``
        (component first, so that per-pose factors broadcast without reshaping). A motion
        whose value is exactly zero for every row (and no joint reading) is the identity and
        is skipped; its recorded frame is the current one.

        Returns R ``(*batch, N, 3, 3)``, o ``(*batch, N, 3)`` and, if `record`, the list of
        (axis vector ``(3, *batch, N)``, origin ``(3, *batch, N)``) before each motion.
        """
        batch = p.shape[:-1]
        N = q.shape[0]
        shape = (3, *batch, N)
        axes = [np.zeros(shape), np.zeros(shape), np.zeros(shape)]
        for i in range(3):
            axes[i][i] = 1.0
        o = np.zeros(shape)
        frames = []
        nonzero = np.any(p != 0.0, axis=tuple(range(p.ndim - 1))) if p.ndim > 1 else p != 0.0
        # one parameter vector: plain floats (cheaper than 0-d arrays in the loop below)
        values = p.tolist() if p.ndim == 1 else None
        for m, k in zip(self.motions, self._motion_index, strict=True):
            if record:  # arrays are replaced, never modified in place: no copies needed
                frames.append((axes[m.axis], o))
            if m.joint is None and not nonzero[k]:
                continue
            # (*batch, 1): broadcast over poses
            value = values[k] if values is not None else p[..., k][..., None]
            u = axes[m.axis]
            if m.kind == TRANSLATION:
                o = o + value * u
                continue
            angle = value + q[:, m.joint] if m.joint is not None else value
            c, s_ = np.cos(angle), np.sin(angle)
            j, l = (m.axis + 1) % 3, (m.axis + 2) % 3
            vj, vl = axes[j], axes[l]
            axes[j] = c * vj + s_ * vl
            axes[l] = c * vl - s_ * vj
        R = np.stack([np.moveaxis(a, 0, -1) for a in axes], axis=-1)
        return R, np.moveaxis(o, 0, -1), frames

    def fk(self, q: ArrayLike, params: ArrayLike | None = None) -> Array:
        """Tool (or flange) frame in the measurement frame.

        Parameters
        ----------
        q : array_like, shape (N, n_joints) or (n_joints,)
            Joint angles (rad).
        params : array_like, shape (n_params,) or (P, n_params), optional
            Parameter vector(s); nominal if omitted.

        Returns
        -------
        ndarray, shape (N, 4, 4) or (P, N, 4, 4)
            ``tool2base`` transforms (lengths in the model unit).
        """
        q = self._check_q(q)
        p = self._check_params(params)
        R, o, _ = self._sweep(q, p, record=False)
        T = np.zeros(R.shape[:-2] + (4, 4))
        T[..., :3, :3] = R
        T[..., :3, 3] = o
        T[..., 3, 3] = 1.0
        return T

    def positions(self, q: ArrayLike, params: ArrayLike | None = None) -> Array:
        """Tool-point positions ``(N, 3)`` or ``(P, N, 3)``; see `fk`."""
        q = self._check_q(q)
        p = self._check_params(params)
        return self._sweep(q, p, record=False)[1]

    def identification_jacobian(
        self, q: ArrayLike, params: ArrayLike | None = None, outputs: str = "position"
    ) -> Array:
        """Analytic derivative of the tool pose with respect to every parameter.

        Parameters
        ----------
        q : array_like, shape (N, n_joints)
            Joint angles (rad).
        params : array_like, shape (n_params,), optional
            Parameter vector; nominal if omitted.
        outputs : {"position", "pose"}
            ``position``: d(x, y, z); ``pose``: additionally the small-rotation vector of the
            tool frame expressed in the measurement frame (rad per unit parameter).

        Returns
        -------
        ndarray, shape (N, 3, n_params) or (N, 6, n_params)
            Length unit per length unit for lengths, length unit per rad for angles.
        """
        return np.ascontiguousarray(self.jacobian_t(q, params, outputs).transpose(2, 1, 0))

    def jacobian_t(
        self, q: ArrayLike, params: ArrayLike | None = None, outputs: str = "position"
    ) -> Array:
        """`identification_jacobian` in parameter-major layout ``(n_params, 3 or 6, N)``.

        Cheaper for solvers that select parameter rows before reshaping.
        """
        return self.sweep(q, params).jacobian_t(outputs)

    def joint_jacobian(
        self, q: ArrayLike, params: ArrayLike | None = None, outputs: str = "pose"
    ) -> Array:
        """Derivative of the tool pose with respect to the joint readings.

        Parameters
        ----------
        q : array_like, shape (N, n_joints)
            Joint readings (rad).
        params : array_like, shape (n_params,), optional
            Parameter vector; nominal if omitted.
        outputs : {"pose", "position"}
            ``pose``: d(x, y, z) and the small-rotation vector of the tool frame in the
            measurement frame; ``position``: d(x, y, z) only.

        Returns
        -------
        ndarray, shape (N, 6, n_joints) or (N, 3, n_joints)
            The geometric Jacobian: length unit per rad (and rad per rad) for a revolute
            joint.
        """
        Jt = self.sweep(q, params).joint_jacobian_t(outputs)
        return np.ascontiguousarray(Jt.transpose(2, 1, 0))

    def sweep(self, q: ArrayLike, params: ArrayLike | None = None) -> Sweep:
        """Forward kinematics of one parameter vector, keeping what the Jacobian needs.

        A solver that needs the positions at ``x`` and then, if the step is accepted, the
        Jacobian at the same ``x`` computes the chain once: ``s = model.sweep(q, p)``,
        ``s.positions``, later ``s.jacobian_t()``.
        """
        q = self._check_q(q)
        p = self._check_params(params)
        if p.ndim != 1:
            raise InputError("identification_jacobian expects one parameter vector")
        R, o_end, frames = self._sweep(q, p, record=True)
        return Sweep(self, o_end, frames, R)


class Sweep:
    """Result of `SerialModel.sweep`: tool poses and the frames before each motion."""

    def __init__(self, model: SerialModel, o_end: Array, frames: list, R: Array) -> None:
        self.model = model
        self.positions = o_end  # (N, 3)
        self.rotations = R  # (N, 3, 3): tool frame orientation in the measurement frame
        self.frames = frames

    def joint_jacobian_t(self, outputs: str = "pose") -> Array:
        """Geometric Jacobian ``(n_joints, 6 or 3, N)`` with respect to the joint readings.

        A joint's reading adds to the value of one motion of the chain, so its column is
        that motion's parameter column of `jacobian_t`.
        """
        return self.jacobian_t(outputs, columns=self.model._joint_columns)

    def jacobian_t(self, outputs: str = "position", columns: ArrayLike | None = None) -> Array:
        """Identification Jacobian ``(n, 3 or 6, N)`` (see `identification_jacobian`).

        `columns` (parameter indices) restricts the rows to those parameters, in that
        order; only their motions are differentiated.
        """
        if outputs not in ("position", "pose"):
            raise InputError(f"outputs: expected 'position' or 'pose', got {outputs!r}")
        model = self.model
        cols = np.arange(model.n_params) if columns is None else np.asarray(columns)
        row_of = np.full(model.n_params, -1)
        row_of[cols] = np.arange(cols.size)
        p_end = self.positions.T  # (3, N)
        rows = 3 if outputs == "position" else 6
        Jt = np.zeros((cols.size, rows, p_end.shape[1]))
        for (u, o), k, is_rot in zip(self.frames, model._motion_index, model._rotation_mask,
                                     strict=True):
            r_ = row_of[k]
            if r_ < 0:
                continue
            if not is_rot:  # a translation moves the point along its axis
                Jt[r_, :3] = u
                continue
            d = p_end - o  # a rotation about u through o: u x (p - o)
            Jt[r_, 0] = u[1] * d[2] - u[2] * d[1]
            Jt[r_, 1] = u[2] * d[0] - u[0] * d[2]
            Jt[r_, 2] = u[0] * d[1] - u[1] * d[0]
            if rows == 6:
                Jt[r_, 3:] = u
        return Jt
