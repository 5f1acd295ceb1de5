"""Six-leg parallel mechanism (Stewart platform) of the parallel-link CMM of papers/004.

Conventions (papers/004 sec. 2.1, eq. 1-5; see ``docs/stewart.md``):

* base frame O_B-XYZ; base joints ``b_i`` in the base frame, platform joints ``p_i`` in
  the platform frame O_P-xyz; the probe tip ``O_s`` sits at ``s = (0, 0, ls)`` in the
  platform frame (``probe_offset``);
* a pose is the probe tip ``(x, y, z, alpha, beta, gamma)``: position of ``O_s`` in the
  base frame and the platform orientation ``R = Rz(gamma) Ry(beta) Rx(alpha)`` (the
  paper's ``[gamma][beta][alpha]``). Angles are radians in the Python API and degrees in
  files and on the command line. The platform centre is ``p_c = p_s - R s``;
* leg vectors ``l_i = R p_i + p_s - R s - b_i`` (eq. 4) and physical leg lengths
  ``|l_i|`` (eq. 5). A machine reads ``|l_i| - o_i`` where ``o_i`` are the leg offsets
  (zero nominally; identified by :mod:`kinecal.calibration.stewart.calibrate`).

This convention reproduces Table 3 of papers/004 to all printed digits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.stewart import forward as forward_solvers
from kinecal.kinematics.stewart import modes, pso
from kinecal.kinematics.stewart.poses import (
    as_poses,
    check_leg_readings,
    degrees_to_radians,
    poses_from_rt,
    radians_to_degrees,
)
from kinecal.spatial import matrix_from_rpy

__all__ = [
    "N_PARAMETERS",
    "PARAMETER_NAMES",
    "StewartPlatform",
    "degrees_to_radians",
    "joint_angles_liu2008",
    "leg_jacobian",
    "poses_from_rt",
    "radians_to_degrees",
]

Array = NDArray[np.float64]

#: names of the 42 geometric parameters (papers/004 geometry, identified by calibration)
PARAMETER_NAMES: tuple[str, ...] = (
    *(f"b{i}.{a}" for i in range(1, 7) for a in "xyz"),
    *(f"p{i}.{a}" for i in range(1, 7) for a in "xyz"),
    *(f"o{i}" for i in range(1, 7)),
)
N_PARAMETERS = len(PARAMETER_NAMES)


def joint_angles_liu2008(base_angle: float, platform_angle: float) -> tuple[Array, Array]:
    """Polar angles of the base and platform joints, papers/004 eq. 2.

    Parameters
    ----------
    base_angle, platform_angle : float
        Short-edge central angles theta_b and theta_p (rad).

    Returns
    -------
    theta_b, theta_p : ndarray, shape (6,)
        Angles of ``b_i`` from the X axis and of ``p_i`` from the x axis (rad).
    """
    d60, d120, d180, d240, d300 = np.deg2rad([60.0, 120.0, 180.0, 240.0, 300.0])
    hb, hp = 0.5 * base_angle, 0.5 * platform_angle
    theta_b = np.array([d60 - hb, d60 + hb, d180 - hb, d180 + hb, d300 - hb, d300 + hb])
    theta_p = np.array([hp, d120 - hp, d120 + hp, d240 - hp, d240 + hp, 2 * np.pi - hp])
    return theta_b, theta_p


def _as_joints(value: ArrayLike, name: str) -> Array:
    a = np.asarray(value, dtype=float)
    if a.shape != (6, 3) or not np.isfinite(a).all():
        raise InputError(f"{name} must be 6 finite (x, y, z) rows, got shape {a.shape}")
    return a.copy()


@dataclass(frozen=True, repr=False)
class StewartPlatform:
    """Geometry and kinematics of a 6-6 Stewart platform measuring machine (papers/004).

    Parameters
    ----------
    base_joints : ndarray, shape (6, 3)
        Base joint centres ``b_i`` in the base frame (length unit, m for papers/004).
    platform_joints : ndarray, shape (6, 3)
        Platform joint centres ``p_i`` in the platform frame (length unit).
    probe_offset : float
        ``ls``: distance of the probe tip from the platform centre along the platform z
        axis (papers/004 Fig. 1b, ``s = (0, 0, ls)``).
    leg_range : (float, float)
        Admissible leg readings ``(l_min, l_max)`` (Table 2).
    leg_offsets : ndarray, shape (6,), optional
        ``o_i``: physical leg length minus reading (zero nominally).
    name : str, optional
        Geometry name (e.g. ``"liu2008-cmm"``).
    """

    base_joints: Array
    platform_joints: Array
    probe_offset: float = 0.0
    leg_range: tuple[float, float] = (0.0, np.inf)
    leg_offsets: Array = field(default_factory=lambda: np.zeros(6))
    name: str | None = None

    def __repr__(self) -> str:
        lo, hi = self.leg_range
        return (f"<StewartPlatform {self.name or '(unnamed)'}: probe offset "
                f"{self.probe_offset:.4g}, leg range {lo:.4g}-{hi:.4g}>")

    def __post_init__(self) -> None:
        object.__setattr__(self, "base_joints", _as_joints(self.base_joints, "base_joints"))
        object.__setattr__(
            self, "platform_joints", _as_joints(self.platform_joints, "platform_joints")
        )
        off = np.asarray(self.leg_offsets, dtype=float)
        if off.shape != (6,) or not np.isfinite(off).all():
            raise InputError(f"leg_offsets must be 6 finite numbers, got shape {off.shape}")
        object.__setattr__(self, "leg_offsets", off.copy())
        lo, hi = (float(v) for v in self.leg_range)
        if not (0.0 <= lo < hi):
            raise InputError(f"leg_range must satisfy 0 <= l_min < l_max, got ({lo}, {hi})")
        object.__setattr__(self, "leg_range", (lo, hi))
        if not np.isfinite(self.probe_offset):
            raise InputError("probe_offset must be finite")
        object.__setattr__(self, "probe_offset", float(self.probe_offset))

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_circles(
        cls,
        base_radius: float,
        platform_radius: float,
        base_angle: float,
        platform_angle: float,
        probe_offset: float,
        leg_range: tuple[float, float],
        name: str | None = None,
    ) -> StewartPlatform:
        """Geometry of papers/004 eq. 1-2: joints on two circles.

        Parameters
        ----------
        base_radius, platform_radius : float
            ``R_b`` and ``R_p`` (length unit).
        base_angle, platform_angle : float
            Short-edge central angles ``theta_b``, ``theta_p`` (rad).
        probe_offset : float
            ``ls`` (length unit).
        leg_range : (float, float)
            ``(l_min, l_max)`` (length unit).
        name : str, optional
            Geometry name.
        """
        tb, tp = joint_angles_liu2008(base_angle, platform_angle)
        b = np.stack([base_radius * np.cos(tb), base_radius * np.sin(tb), np.zeros(6)], -1)
        p = np.stack([platform_radius * np.cos(tp), platform_radius * np.sin(tp), np.zeros(6)], -1)
        return cls(b, p, probe_offset, leg_range, np.zeros(6), name)

    @classmethod
    def liu2008(cls) -> StewartPlatform:
        """The parallel-link CMM of papers/004 Table 2 (m): Rb 0.5, Rp 0.225, ls 0.18."""
        return cls.from_circles(
            0.5, 0.225, np.deg2rad(30.0), np.deg2rad(30.0), 0.18, (0.75, 0.97), "liu2008-cmm"
        )

    # ------------------------------------------------------------------ parameters
    @property
    def probe_vector(self) -> Array:
        """``s = (0, 0, ls)``, shape (3,): probe tip in the platform frame."""
        return np.array([0.0, 0.0, self.probe_offset])

    @property
    def tip_joints(self) -> Array:
        """``q_i = p_i - s``, shape (6, 3): platform joints relative to the probe tip."""
        return self.platform_joints - self.probe_vector

    @property
    def parameters(self) -> Array:
        """The 42 geometric parameters, shape (42,), ordered as `PARAMETER_NAMES`."""
        return np.concatenate(
            [self.base_joints.ravel(), self.platform_joints.ravel(), self.leg_offsets]
        )

    def with_parameters(self, params: ArrayLike) -> StewartPlatform:
        """A copy with the 42 parameters (order of `PARAMETER_NAMES`) replaced."""
        v = np.asarray(params, dtype=float)
        if v.shape != (N_PARAMETERS,):
            raise InputError(f"expected {N_PARAMETERS} parameters, got shape {v.shape}")
        return StewartPlatform(
            v[:18].reshape(6, 3),
            v[18:36].reshape(6, 3),
            self.probe_offset,
            self.leg_range,
            v[36:],
            self.name,
        )

    # ------------------------------------------------------------------ inverse kinematics
    def leg_vectors(self, poses: ArrayLike) -> Array:
        """Leg vectors ``l_i`` of papers/004 eq. 4.

        Parameters
        ----------
        poses : array_like, shape (..., 6)
            Probe poses (x, y, z, alpha, beta, gamma), length unit and rad.

        Returns
        -------
        ndarray, shape (..., 6, 3)
            ``R (p_i - s) + p_s - b_i`` in the base frame (length unit).
        """
        x = as_poses(poses)
        R = matrix_from_rpy(x[..., 3:])
        return self.leg_vectors_from(R, x[..., :3])

    def leg_vectors_from(self, R: Array, t: Array) -> Array:
        """Leg vectors ``(..., 6, 3)`` from rotations ``(..., 3, 3)`` and tips ``(..., 3)``."""
        q = self.tip_joints
        rq = np.sum(R[..., None, :, :] * q[:, None, :], axis=-1)
        return rq + t[..., None, :] - self.base_joints

    def inverse(self, poses: ArrayLike) -> Array:
        """Leg readings for probe poses: papers/004 eq. 4-5, minus the leg offsets.

        Parameters
        ----------
        poses : array_like, shape (..., 6)
            Probe poses (x, y, z, alpha, beta, gamma), length unit and rad.

        Returns
        -------
        ndarray, shape (..., 6)
            Leg readings ``|l_i| - o_i`` (length unit).
        """
        return np.linalg.norm(self.leg_vectors(poses), axis=-1) - self.leg_offsets

    def pose_jacobian(self, poses: ArrayLike) -> Array:
        """Derivative of the leg lengths by the probe twist.

        Parameters
        ----------
        poses : array_like, shape (..., 6)
            Probe poses (length unit, rad).

        Returns
        -------
        ndarray, shape (..., 6, 6)
            Row i is ``[n_i, (R q_i) x n_i]`` with ``n_i`` the unit leg vector: the change of
            ``|l_i|`` per translation of the tip and per small rotation (rad) about base axes
            through the tip.
        """
        x = as_poses(poses)
        R = matrix_from_rpy(x[..., 3:])
        return leg_jacobian(R, self.leg_vectors_from(R, x[..., :3]), self.tip_joints)

    def check_legs(self, legs: ArrayLike, *, file: str | None = None, row_offset: int = 1) -> Array:
        """Validated leg readings ``(N, 6)`` (length unit) from ``(6,)`` or ``(N, 6)``:
        finite, inside `leg_range`; an `InputError` names the first bad row, counting from
        `row_offset`, and `file` (`kinecal.kinematics.stewart.poses.check_leg_readings`)."""
        return check_leg_readings(legs, self.leg_range, file=file, row_offset=row_offset)

    # ------------------------------------------------------------------ forward kinematics
    def neutral_pose(self) -> Array:
        """Home pose, shape (6,): no rotation, tip above the origin, legs near mid-range."""
        q, b = self.tip_joints, self.base_joints
        lo, hi = self.leg_range
        mid = 0.5 * (lo + hi) if np.isfinite(hi) else lo + 1.0
        h2 = np.sum((q[:, :2] - b[:, :2]) ** 2, axis=1)
        z = np.sqrt(np.maximum(mid**2 - h2, 0.0)) - q[:, 2] + b[:, 2]
        return np.array([0.0, 0.0, float(np.mean(z)), 0.0, 0.0, 0.0])

    def workspace_box(self) -> Array:
        """Default pose box, shape (6, 2) (see `modes.workspace_box`)."""
        return modes.workspace_box(self)

    def random_poses(
        self, n: int, rng: np.random.Generator | int | None = None, box: ArrayLike | None = None
    ) -> Array:
        """``n`` random reachable poses ``(n, 6)`` (see `modes.random_poses`)."""
        return modes.random_poses(self, n, rng, box)

    def forward(
        self,
        legs: ArrayLike,
        method: str = "newton",
        *,
        x0: ArrayLike | None = None,
        rng: np.random.Generator | int | None = None,
        on_failure: str = "raise",
        options: dict | None = None,
    ):
        """Forward kinematics: probe poses from leg readings (papers/004 sec. 2.2).

        Parameters
        ----------
        legs : array_like, shape (6,) or (N, 6)
            Leg readings (length unit), checked against `leg_range`.
        method : {"newton", "pso"}
            ``newton``: batched damped Newton-Raphson on ``|l_i| - L_i`` with the analytic
            Jacobian `pose_jacobian`, from `x0` or the neutral pose, with multi-start
            retries for rows that do not converge. ``pso``: the paper's solver, particle
            swarm on eq. 6 (see :func:`kinecal.kinematics.stewart.pso.forward_pso`)
        x0 : array_like, shape (6,) or (N, 6), optional
            Start poses for newton (default: `neutral_pose`).
        rng : Generator or int, optional
            Random generator or seed (pso, and newton's retries).
        on_failure : {"raise", "flag"}
            ``raise``: an `InputError` names the first row without a real solution (newton)
            or that missed the target (pso); ``flag``: return ``converged = False``.
        options : dict, optional
            Solver options (newton: ``tol``, ``max_iter``; pso: ``popsize``, ``maxiter``,
            ``target``, ``w_max``, ``w_min``, ``c1``, ``c2``, ``vmax``, ``bounds``).

        Returns
        -------
        ForwardResult
            ``poses (N, 6)``, ``converged (N,)``, ``residual (N,)`` (max abs leg error),
            ``iterations (N,)``, ``elapsed`` (s).
        """
        L = self.check_legs(legs)
        if on_failure not in ("raise", "flag"):
            raise InputError("on_failure must be 'raise' or 'flag'", option="on_failure")
        if method == "newton":
            res = forward_solvers.forward_newton(self, L, x0=x0, rng=rng, **(options or {}))
        elif method == "pso":
            res = pso.forward_pso(self, L, rng=rng, **(options or {}))
        else:
            raise InputError(f"unknown method {method!r}; expected newton or pso", option="method")
        if on_failure == "raise" and not res.converged.all():
            i = int(np.argmin(res.converged))
            what = "no real solution found" if method == "newton" else "PSO missed the target"
            raise InputError(
                f"{what} for leg lengths {np.array2string(L[i], precision=6)} "
                f"(residual {res.residual[i]:.3g})",
                row=i + 1,
            )
        return res

    def forward_all(self, legs: ArrayLike, **kwargs):
        """Every real assembly mode for one set of leg readings.

        See :func:`kinecal.kinematics.stewart.modes.forward_all`.
        """
        return modes.forward_all(self, legs, **kwargs)


def leg_jacobian(R: Array, legs: Array, q: Array) -> Array:
    """Jacobian ``(..., 6, 6)`` of leg lengths by tip twist (see `pose_jacobian`).

    Parameters
    ----------
    R : ndarray, shape (..., 3, 3)
        Platform orientations.
    legs : ndarray, shape (..., 6, 3)
        Leg vectors ``l_i``.
    q : ndarray, shape (6, 3)
        Platform joints relative to the probe tip, platform frame.
    """
    n = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
    rq = np.sum(R[..., None, :, :] * q[:, None, :], axis=-1)
    return np.concatenate([n, np.cross(rq, n)], axis=-1)
