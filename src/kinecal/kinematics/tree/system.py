"""`SystemModel`: several serial chains from one root sharing links, joints and parameters.

A robot system is a tree of links (a torso with two arms and a head; a robot on a rail
beside a positioner): every chain runs from the root to a *tip*, and the elements chains
have in common (the torso, the rail) are shared parameters. The system is not a new
kinematics engine: each tip is a serial chain of elementary motions on the system's
parameter vector (`kinecal.kinematics.tree.chain`), and the forward kinematics and Jacobian
of a row are its chain's (`kinecal.kinematics.tree.forward`).

The model offers the interface of `kinecal.kinematics.serial.SerialModel` that the
calibration uses (parameters, joints, ``positions``, ``fk``, ``sweep``, ``jacobian_t``,
``joint_jacobian``, ``with_params``), with one difference: the per-row point index that
a serial arm's markers use is the row's **tip** (``marker_names`` are the tip names), so
that the residual blocks of every measurement kind work on a system unchanged.

Public entry points beside those: `link_poses` and `link_sweep` (the pose of any link of
the system for each row, and its Jacobian: what cameras, boards and carried points
mounted on a link need), `link_points` (points fixed in a link), `tip_model` (one tip's
chain as a `SerialModel`, for inverse kinematics and compensation), `chain_parameters`,
`chain_joints`, `shared_parameters`.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.motions import PRISMATIC
from kinecal.kinematics.serial.parameters import ParameterVector
from kinecal.kinematics.tree.elements import Element, Tip
from kinecal.kinematics.tree.forward import SystemKinematics, SystemSweep
from kinecal.kinematics.tree.layout import build_layout, link_chain

__all__ = ["SystemModel", "is_system"]

Array = NDArray[np.float64]


def is_system(model: object) -> bool:
    """True for a `SystemModel` (what the readers and commands branch on)."""
    return isinstance(model, SystemModel)


class SystemModel(SystemKinematics, ParameterVector):
    """A robot system (module docstring).

    Parameters
    ----------
    name : str
    elements : sequence of Element
        The tree's joints and frames (`kinecal.kinematics.tree.elements`); elements on
        no path to a tip or to one of `links` are left out.
    tips : sequence of Tip
        The chains' ends, in order (the tip index of a row is a position here).
    root : str
        The root link (the measurement frame: ``world``).
    length_unit : str
    angle_unit : {"deg", "rad"}
        Unit of revolute readings in measurement files.
    tolerances : dict, optional
        ``{"length": L, "angle": A}`` (search box of the metaheuristics).
    fixed : sequence of str, optional
        Further parameters held by default.
    description : str
    links : sequence of str, optional
        Further links to reach (e.g. a carrier link that is no tip).
    source : dict, optional
        Where the system came from (``{"urdf": path, "base_link": ..}`` or
        ``{"system": path}``): what an export or a result needs to rebuild it.
    """

    convention = "system"
    joint_errors = None
    _joint_terms = None
    markers = None
    base = None
    tool = None

    def __init__(self, name: str, elements: Sequence[Element], tips: Sequence[Tip], *,
                 root: str = "world", length_unit: str = "m", angle_unit: str = "deg",
                 tolerances: Mapping | None = None, fixed: Sequence[str] = (),
                 description: str = "", links: Sequence[str] = (),
                 source: Mapping | None = None) -> None:
        if angle_unit not in ("rad", "deg"):
            raise InputError(f"angle_unit: expected rad or deg, got {angle_unit!r}")
        self.name = str(name)
        self.length_unit = str(length_unit)
        self.angle_unit = angle_unit
        self.description = description
        self.root = root
        self.source = dict(source or {})
        self._elements = list(elements)
        self._tips = list(tips)
        self._links = list(links)
        lay = self._layout = build_layout(self._elements, self._tips, root, self._links)
        self._names = tuple(lay.names)
        self._index = {n: k for k, n in enumerate(self._names)}
        self._nominal = lay.nominal.copy()
        self._chains = [lay.chains[t.name] for t in self._tips]
        self._link_chains: dict = {}
        unknown = sorted(set(fixed) - set(self._names))
        if unknown:
            raise InputError(f"fixed: unknown parameter(s) {unknown}")
        self.fixed = tuple(fixed)
        self._fixed = frozenset(lay.frozen | set(fixed))
        self.tolerances = {"length": 1.0, "angle": 0.02, **(tolerances or {})}
        self.joint_limits = lay.limits.copy()
        self.motions = max((c.motions for c in self._chains), key=len)

    def __repr__(self) -> str:
        return (f"<SystemModel {self.name}: tips {', '.join(self.tips)}, {self.n_joints} "
                f"joints, {self.n_params} parameters, {self.length_unit}/{self.angle_unit}>")

    # ------------------------------------------------------------------ tips and joints
    @property
    def tips(self) -> tuple[str, ...]:
        """Tip names, in order."""
        return tuple(t.name for t in self._tips)

    @property
    def marker_names(self) -> tuple[str, ...]:
        """The tips: the per-row point index of the measurement data names a row's tip
        (module docstring)."""
        return self.tips

    @property
    def marker_set(self) -> None:
        return None

    def tip_link(self, tip: str) -> str:
        """The link tip `tip` sits on."""
        return self._tips[self.tip_number(tip)].link

    def tip_number(self, tip: str) -> int:
        """Position of `tip` in `tips`; `InputError` naming the tips when unknown."""
        names = self.tips
        if tip not in names:
            raise InputError(f"unknown tip {tip!r}; the system's tips are {', '.join(names)}",
                             option="--tip")
        return names.index(tip)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The system's joints (reading columns), in order."""
        return tuple(self._layout.joints)

    @property
    def n_joints(self) -> int:
        """Number of independent joint readings."""
        return len(self._layout.joints)

    @property
    def joint_kinds(self) -> tuple[str, ...]:
        return tuple(self._layout.kinds)

    def is_prismatic(self) -> NDArray[np.bool_]:
        """Mask ``(n_joints,)`` of prismatic joints."""
        return np.array([k == PRISMATIC for k in self._layout.kinds])

    def joint_scale(self, angle_unit: str | None = None) -> Array:
        """Factor per joint from file units to the API's (as `SerialModel.joint_scale`)."""
        unit = self.angle_unit if angle_unit is None else angle_unit
        if unit not in ("deg", "rad"):
            raise InputError(f"angle unit: expected deg or rad, got {unit!r}")
        return np.where(self.is_prismatic(), 1.0, np.pi / 180.0 if unit == "deg" else 1.0)

    def chain_joints(self, tip: str) -> NDArray[np.intp]:
        """Indices of the system joints a row of `tip` reads (its chain's joints and the
        leaders of its coupled joints), in joint order."""
        return np.unique(self._chains[self.tip_number(tip)].source)

    def chain_links(self, tip: str) -> tuple[str, ...]:
        """The links on the chain of `tip`, root first (the tip's link last)."""
        path = self._layout.paths[self.tip_link(tip)]
        return (self.root, *(e.child for e in path))

    def link_joints(self, link: str) -> NDArray[np.intp]:
        """Indices of the system joints the pose of `link` depends on."""
        return np.unique(self._link_chain(link).source)

    # ------------------------------------------------------------------ parameters

    @property
    def _n_geometric(self) -> int:
        return len(self._names)

    def index(self, names: Sequence[str]) -> NDArray[np.intp]:
        """Indices of `names` in the parameter vector; `InputError` for unknown names."""
        missing = [n for n in names if n not in self._index]
        if missing:
            shown = ", ".join(self._names[:20]) + (" ..." if len(self._names) > 20 else "")
            raise InputError(f"unknown parameter(s) {missing}; system {self.name!r} has "
                             f"{shown}")
        return np.array([self._index[n] for n in names], dtype=np.intp)

    def is_angle(self) -> NDArray[np.bool_]:
        return self._layout.angle.copy()

    def chain_parameters(self, tip: str) -> tuple[str, ...]:
        """The parameters the chain of `tip` reaches (its motions, multipliers, tool)."""
        c = self._chains[self.tip_number(tip)]
        used = set(c._motion_index.tolist()) | set(c.multiplier[c.multiplier >= 0].tolist())
        return tuple(n for k, n in enumerate(self._names) if k in used)

    def shared_parameters(self) -> tuple[str, ...]:
        """Parameters two or more chains reach (the shared links and joints)."""
        count: dict[str, int] = {}
        for t in self.tips:
            for n in self.chain_parameters(t):
                count[n] = count.get(n, 0) + 1
        return tuple(n for n in self._names if count.get(n, 0) > 1)

    def parameter_owner(self, name: str) -> str:
        """The joint, frame or tool a parameter belongs to (words)."""
        self.index([name])
        return self._layout.owners[name]

    def with_params(self, params: ArrayLike, name: str | None = None) -> SystemModel:
        """A copy whose nominal values are `params` ``(n_params,)``."""
        p = self._one_vector(params)
        out = copy.copy(self)
        out._nominal = np.array(p, dtype=float)
        out._link_chains = {}
        if name is not None:
            out.name = str(name)
        return out

    @property
    def elements(self) -> list:
        """The elements on the system's paths (coupled joints resolved), in path order."""
        return list(self._layout.elements)

    def tip_spec(self, tip: str) -> Tip:
        """The `Tip` named `tip`."""
        return self._tips[self.tip_number(tip)]

    # ------------------------------------------------------------------ links
    def _link_chain(self, link: str, point: bool = False):
        key = (link, point)
        if key not in self._link_chains:
            self._link_chains[key] = link_chain(self._layout, link, point)
        return self._link_chains[key]

    @property
    def links(self) -> tuple[str, ...]:
        """Every link the system reaches (root, links on the chains, tips' links)."""
        return tuple(self._layout.paths)

    def link_poses(self, q: ArrayLike, link: str, params: ArrayLike | None = None) -> Array:
        """Pose of `link` in the measurement frame for each row ``(N, 4, 4)``
        (``link2world``; `q` the system's readings ``(N, n_joints)``, rad)."""
        q, p = self._check_q(q), self._one_vector(params)
        chain = self._link_chain(link)
        if not chain.motions:
            return np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        return chain.fk(chain.chain_q(q, p), p)

    def link_sweep(self, q: ArrayLike, link: str, params: ArrayLike | None = None
                   ) -> SystemSweep:
        """The sweep of `link`'s frame for each row: ``positions`` ``(N, 3)`` (its origin),
        ``rotations`` ``(N, 3, 3)`` and ``jacobian_t(outputs, columns)`` ``(k, 3 or 6, N)``
        (the derivative of the origin and, with ``"pose"``, of the frame's small rotation
        with respect to the system parameters `columns`): what a camera or board mounted
        on a link needs."""
        q, p = self._check_q(q), self._one_vector(params)
        chain = self._link_chain(link)
        if not chain.motions:
            raise InputError(f"link {link!r} is the measurement frame itself: it does not move")
        return SystemSweep([(chain, slice(None), chain.sweep(chain.chain_q(q, p), p), q)],
                           len(q), p)

    def link_points(self, q: ArrayLike, link: str, points: ArrayLike,
                    params: ArrayLike | None = None, columns: ArrayLike | None = None
                    ) -> tuple[Array, Array | None, Array]:
        """Points fixed in `link` for each row, in the measurement frame.

        Parameters
        ----------
        q : array_like, shape (N, n_joints)
        link : str
        points : array_like, shape (N, 3)
            Each row's point in the link's frame (length unit).
        params : array_like, shape (n_params,), optional
        columns : array_like of int, optional
            System parameter indices to differentiate (None: positions only).

        Returns
        -------
        positions : ndarray, shape (N, 3)
        jacobian : ndarray, shape (k, 3, N) or None
            Derivative of the positions with respect to `columns`.
        rotations : ndarray, shape (N, 3, 3)
            The link's orientation per row: the derivative with respect to the point.
        """
        q, p = self._check_q(q), self._one_vector(params)
        P = np.asarray(points, dtype=float).reshape(len(q), 3)
        chain = self._link_chain(link, point=True).with_points(P)
        pe, qc = chain.point_vector(p), chain.chain_q(q, p)
        s = chain.sweep(qc, pe)
        n = self.n_params
        R = s.jacobian_t(columns=n + np.arange(3)).transpose(2, 1, 0)  # (N, 3, 3)
        if columns is None:
            return s.positions, None, R
        cols = np.asarray(columns, dtype=np.intp)
        J = s.jacobian_t(columns=cols)
        chain.multiplier_rows(J, cols, q, p, lambda c: s.jacobian_t(columns=c))
        return s.positions, J, R

    # ------------------------------------------------------------------ serial views
    def tip_model(self, tip: str, params: ArrayLike | None = None):
        """The chain of `tip` at `params` (default nominal) as a ``urdf`` `SerialModel`
        with the chain's joints (system joint names): for inverse kinematics and
        compensation (`kinecal.kinematics.tree.serial_view`)."""
        from kinecal.kinematics.tree.serial_view import tip_model

        return tip_model(self, tip, params)
