"""In-memory measurement data: joint readings with measured tool-point positions
(`Measurements`), with what a gauge says about the tool point (`GaugeMeasurements`:
ballbar and pair distances, fixed points, planes), and repeated measurements of commanded
poses (`RepeatedPoses`, the ISO 9283 tests of `kinecal.metrology.iso9283`).

Readers and writers of the files live in `kinecal.io.measurements`; the type sits below
both the file layer and the calibration layer, so that neither imports the other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.spatial import check_rotation

__all__ = ["DISTANCE_KINDS", "GAUGE_KINDS", "KNOWN_COLUMNS", "GaugeMeasurements",
           "Measurements", "RepeatedPoses"]


@dataclass(frozen=True, repr=False)
class Measurements:
    """Joint readings with measured tool-point positions (and optionally orientations).

    Attributes
    ----------
    q : ndarray, shape (N, n_joints)
        Joint angles (rad).
    xyz : ndarray, shape (N, 3)
        Measured tool-point positions in the measurement frame (model length unit).
    weights : ndarray, shape (N,) or None
        Optional per-pose weights (relative, > 0).
    source : str
        Where the data came from (file path or description).
    rotations : ndarray, shape (N, 3, 3) or None
        Measured tool-frame orientations in the measurement frame (6-DoF trackers, camera
        poses); None for position-only measurements.
    marker : ndarray of int, shape (N,) or None
        Which marker each pose measured (several tool points on one flange): an index into
        `marker_names`; None when the arm carries one tool point.
    marker_names : tuple of str
        Names of the markers `marker` indexes (the model's markers, in its order).
    station : ndarray of int, shape (N,) or None
        Which tracker set-up (station) measured each pose, an index into `station_names`:
        each station has its own base frame (``base@NAME.x ..``; docs/measurement-kinds.md).
        None: one set-up, the model's base frame.
    station_names : tuple of str
        Names of the stations `station` indexes, in order of first appearance.
    sigma : ndarray, shape (N, 3) or (N, 6), or None
        Per-row standard deviations of the measured coordinates: x, y, z (length unit)
        and, with orientations, of the small rotation about the measurement frame's x, y,
        z axes (rad). They weight the residual rows (`kinecal.calibration.serial.
        row_weights`) together with `sigma_floor`.
    sigma_floor : ndarray, shape (2,), or None
        The unmodelled error added to `sigma` in the weights (position in the length unit,
        rotation in rad); None until a calibration estimates it (the rows are then
        weighted as if `sigma` were absent).
    temperature : ndarray, shape (N,) or None
        Temperature at each pose (deg C), carried into the report.
    time : ndarray, shape (N,) or None
        When each pose was measured (s; from ISO 8601 dates: s since 1970-01-01 UTC):
        time-ordered data are cross-validated in blocks of time as well.
    """

    q: NDArray[np.float64]
    xyz: NDArray[np.float64]
    weights: NDArray[np.float64] | None = None
    source: str = ""
    rotations: NDArray[np.float64] | None = None
    marker: NDArray[np.intp] | None = None
    marker_names: tuple[str, ...] = ()
    station: NDArray[np.intp] | None = None
    station_names: tuple[str, ...] = ()
    sigma: NDArray[np.float64] | None = None
    sigma_floor: NDArray[np.float64] | None = None
    temperature: NDArray[np.float64] | None = None
    time: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        q = np.asarray(self.q, dtype=float)
        xyz = np.asarray(self.xyz, dtype=float)
        if q.ndim != 2 or xyz.shape != (q.shape[0], 3):
            raise InputError(
                f"measurements: expected q (N, n) and xyz (N, 3), got {q.shape} and {xyz.shape}"
            )
        if not (np.isfinite(q).all() and np.isfinite(xyz).all()):
            raise InputError("measurements contain NaN or infinite values")
        if self.weights is not None:
            w = np.asarray(self.weights, dtype=float)
            if w.shape != (q.shape[0],) or not (w > 0).all():
                raise InputError("weights: expected one positive value per pose")
        if self.rotations is not None:
            R = np.asarray(self.rotations, dtype=float)
            if R.shape != (q.shape[0], 3, 3):
                raise InputError(f"rotations: expected shape ({q.shape[0]}, 3, 3), got {R.shape}")
            check_rotation(R, tol=1e-6, name="measured rotation")
        if self.marker is not None:
            m = np.asarray(self.marker)
            if m.shape != (q.shape[0],) or not np.issubdtype(m.dtype, np.integer):
                raise InputError(f"marker: expected {q.shape[0]} integer indices, got {m.shape}")
            if m.size and (m.min() < 0 or m.max() >= len(self.marker_names)):
                raise InputError(f"marker: indices must lie in 0..{len(self.marker_names) - 1} "
                                 f"(marker_names {list(self.marker_names)})")
        elif self.marker_names:
            raise InputError("marker_names without marker indices")
        for name in ("temperature", "time"):
            v = getattr(self, name)
            if v is not None and (np.shape(v) != (q.shape[0],)
                                  or not np.isfinite(np.asarray(v, dtype=float)).all()):
                raise InputError(f"{name}: expected {q.shape[0]} finite values")
        self._check_stations_and_sigma(q.shape[0])

    def _check_stations_and_sigma(self, n: int) -> None:
        if self.station is not None:
            st = np.asarray(self.station)
            if st.shape != (n,) or not np.issubdtype(st.dtype, np.integer) or (
                    st.size and (st.min() < 0 or st.max() >= len(self.station_names))):
                raise InputError(f"station: expected {n} indices into the station names "
                                 f"{list(self.station_names)}")
        elif self.station_names:
            raise InputError("station_names without station indices")
        if self.sigma is not None:
            s = np.asarray(self.sigma, dtype=float)
            rows = 3 if self.rotations is None else 6
            if s.shape != (n, rows) or not np.isfinite(s).all() or (s < 0).any():
                raise InputError(f"sigma: expected ({n}, {rows}) finite standard deviations "
                                 f">= 0, got shape {s.shape}")
        if self.sigma_floor is not None:
            f = np.asarray(self.sigma_floor, dtype=float)
            if f.shape != (2,) or not np.isfinite(f).all() or (f < 0).any():
                raise InputError("sigma_floor: expected 2 finite values >= 0")

    def __repr__(self) -> str:
        what = "poses" + (" with orientations" if self.rotations is not None else "")
        markers = f", markers {', '.join(self.marker_names)}" if self.marker_names else ""
        if self.station_names:
            markers += f", stations {', '.join(self.station_names)}"
        src = f" from {self.source}" if self.source else ""
        return f"<Measurements {len(self)} {what}, {np.shape(self.q)[1]} joints{markers}{src}>"

    def __len__(self) -> int:
        return int(np.shape(self.q)[0])

    def subset(self, index: NDArray[np.intp]) -> Measurements:
        """The poses selected by `index`."""
        w = None if self.weights is None else np.asarray(self.weights)[index]
        R = None if self.rotations is None else np.asarray(self.rotations)[index]
        m = None if self.marker is None else np.asarray(self.marker)[index]
        st = None if self.station is None else np.asarray(self.station)[index]
        sg = None if self.sigma is None else np.asarray(self.sigma)[index]
        extra = {k: None if getattr(self, k) is None else np.asarray(getattr(self, k))[index]
                 for k in ("temperature", "time")}
        return Measurements(np.asarray(self.q)[index], np.asarray(self.xyz)[index], w,
                            f"{self.source}[subset]", R, m, self.marker_names, st,
                            self.station_names if st is not None else (), sg,
                            self.sigma_floor, **extra)


#: measurement kinds of `GaugeMeasurements` -> the CSV column naming each row's group
GAUGE_KINDS: dict[str, str] = {"ballbar": "pivot", "pair": "pair", "point": "point",
                               "plane": "plane"}
#: the kinds whose rows carry a measured (or known) distance
DISTANCE_KINDS = ("ballbar", "pair")
#: the kinds whose groups may be known fixtures -> the columns giving them (base frame)
KNOWN_COLUMNS: dict[str, tuple[str, ...]] = {
    "point": ("px", "py", "pz"), "plane": ("px", "py", "pz", "nx", "ny", "nz")}
KNOWN_SIZES = {k: len(v) for k, v in KNOWN_COLUMNS.items()}


@dataclass(frozen=True, repr=False)
class GaugeMeasurements:
    """Joint readings measured against a gauge: distances, fixed points, planes.

    One file of one kind (``docs/measurement-kinds.md``); rows sharing a group id belong
    to one unknown object (a pivot, a bar, a socket, a plane) that the calibration solves
    for with the arm.

    Attributes
    ----------
    kind : {"ballbar", "pair", "point", "plane"}
        ``ballbar``: the distance from an unknown fixed pivot (one per group) to the tool
        point; ``pair``: the two rows of a group are two tool points `distance` apart;
        ``point``: the tool point is on one unknown fixed point per group; ``plane``: on
        one unknown plane per group.
    q : ndarray, shape (N, n_joints)
        Joint readings (rad; prismatic joints in the length unit).
    group : ndarray of int, shape (N,)
        Group of each row: an index into `group_names`.
    group_names : tuple of str
        The group ids as the file writes them (pivot, pair, point or plane ids).
    distance : ndarray, shape (N,) or None
        ``ballbar`` and ``pair``: the distance of each row (model length unit).
    sigma : ndarray, shape (N,) or None
        Stated 1-sigma noise per row (model length unit; see `kinecal.calibration.blocks`
        for what it is the noise of in each kind), or None.
    source : str
        Where the data came from (file path or description).
    marker : ndarray of int, shape (N,) or None
        Which marker (tool point) each row used, as in `Measurements`; with a robot
        system, the row's tip (`kinecal.kinematics.tree.SystemModel`).
    marker_names : tuple of str
    known : ndarray, shape (G, 3) or (G, 6), or None
        ``point`` and ``plane`` only: per group, its known position in the base frame (a
        calibration block's socket, a fixture's face): ``px, py, pz`` of a point, or a
        point ``px, py, pz`` of a plane and its unit normal ``nx, ny, nz`` (length unit);
        a row of NaN for a group that is unknown (solved with the arm). None: every group
        unknown.
    carrier : ndarray of int, shape (N,) or None
        ``point`` rows of a robot system: the link that carries the touched point (an
        index into `carrier_names`; -1: the point is fixed in the measurement frame). A
        probe on an arm touching a workpiece on a positioner: the positioner's table.
    carrier_names : tuple of str
    """

    kind: str
    q: NDArray[np.float64]
    group: NDArray[np.intp]
    group_names: tuple[str, ...]
    distance: NDArray[np.float64] | None = None
    sigma: NDArray[np.float64] | None = None
    source: str = ""
    marker: NDArray[np.intp] | None = None
    marker_names: tuple[str, ...] = ()
    known: NDArray[np.float64] | None = None
    carrier: NDArray[np.intp] | None = None
    carrier_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in GAUGE_KINDS:
            raise InputError(f"kind: expected one of {', '.join(GAUGE_KINDS)}, got "
                             f"{self.kind!r}")
        q = np.asarray(self.q, dtype=float)
        n = q.shape[0] if q.ndim == 2 else -1
        if n < 0 or not np.isfinite(q).all():
            raise InputError(f"{self.kind} measurements: expected finite q (N, n), got "
                             f"{q.shape}")
        g = np.asarray(self.group)
        if g.shape != (n,) or not np.issubdtype(g.dtype, np.integer) or (
                n and (g.min() < 0 or g.max() >= len(self.group_names))):
            raise InputError(f"group: expected {n} indices into {len(self.group_names)} "
                             "group names")
        needs = self.kind in DISTANCE_KINDS
        if needs != (self.distance is not None):
            raise InputError(f"{self.kind} measurements: distances "
                             + ("missing" if needs else "given to a kind without them"))
        for name in ("distance", "sigma"):
            v = getattr(self, name)
            if v is not None:
                v = np.asarray(v, dtype=float)
                if v.shape != (n,) or not np.isfinite(v).all() or not (v > 0).all():
                    raise InputError(f"{name}: expected {n} positive finite values")
        if self.marker is not None:
            m = np.asarray(self.marker)
            if m.shape != (n,) or (m.size and (m.min() < 0 or m.max() >= len(self.marker_names))):
                raise InputError(f"marker: expected {n} indices into {list(self.marker_names)}")
        elif self.marker_names:
            raise InputError("marker_names without marker indices")
        if self.carrier is not None:
            c = np.asarray(self.carrier)
            if self.kind != "point" or c.shape != (n,) or (
                    c.size and (c.min() < -1 or c.max() >= len(self.carrier_names))):
                raise InputError(f"carrier: expected {n} indices into "
                                 f"{list(self.carrier_names)} (or -1) of point rows")
        if self.known is not None:
            self._check_known()

    def _check_known(self) -> None:
        size = KNOWN_SIZES.get(self.kind)
        if size is None:
            raise InputError(f"known: {self.kind} measurements have no known geometry (points "
                             "and planes do)")
        k = np.asarray(self.known, dtype=float)
        if k.shape != (len(self.group_names), size):
            raise InputError(f"known: expected shape ({len(self.group_names)}, {size}) "
                             f"({', '.join(KNOWN_COLUMNS[self.kind])} per {self.kind} id), "
                             f"got {k.shape}")
        given = ~np.isnan(k).all(axis=1)
        if not np.isfinite(k[given]).all():
            raise InputError(f"known: each {self.kind}'s row must be all numbers (known) or "
                             "all NaN (unknown)")
        if size == 6 and given.any():
            norm = np.linalg.norm(k[given, 3:], axis=1)
            if np.abs(norm - 1.0).max() > 1e-9:
                raise InputError("known: plane normals nx, ny, nz must be unit vectors")

    @property
    def known_groups(self) -> NDArray[np.bool_]:
        """Whether each group's geometry is known ``(G,)``."""
        if self.known is None:
            return np.zeros(len(self.group_names), dtype=bool)
        return ~np.isnan(np.asarray(self.known, dtype=float)).all(axis=1)

    def __repr__(self) -> str:
        src = f" from {self.source}" if self.source else ""
        known = int(self.known_groups.sum())
        more = f" ({known} known)" if known else ""
        return (f"<GaugeMeasurements {self.kind}: {len(self)} rows, {len(self.group_names)} "
                f"groups{more}{src}>")

    def __len__(self) -> int:
        return int(np.shape(self.q)[0])


@dataclass(frozen=True, repr=False)
class RepeatedPoses:
    """Measurements of P commanded poses, each measured once in each of n cycles.

    Attributes
    ----------
    labels : tuple of str, length P
        Pose names, in the order of the test.
    cycles : ndarray of int, shape (n,)
        Cycle numbers (increasing).
    measured : ndarray, shape (P, n, 3)
        Measured positions (length unit), ``measured[i, j]`` pose i in cycle j.
    commanded : ndarray, shape (P, 3)
        Commanded positions (length unit).
    measured_rotations : ndarray, shape (P, n, 3, 3), optional
        Measured orientations (rotation matrices), None for position-only instruments.
    commanded_rotations : ndarray, shape (P, 3, 3), optional
        Commanded orientations.
    joints : ndarray, shape (P, n_joints), optional
        Commanded joint values (rad; prismatic: length unit) when the commanded poses come
        from a model's forward kinematics.
    length_unit : str
        Unit of the positions (a label).
    source : str
        Where the data came from.
    """

    labels: tuple[str, ...]
    cycles: NDArray[np.int64]
    measured: NDArray[np.float64]
    commanded: NDArray[np.float64]
    measured_rotations: NDArray[np.float64] | None = None
    commanded_rotations: NDArray[np.float64] | None = None
    joints: NDArray[np.float64] | None = None
    length_unit: str = "mm"
    source: str = ""

    def __post_init__(self) -> None:
        m = np.asarray(self.measured, dtype=float)
        p = len(self.labels)
        if m.ndim != 3 or m.shape[0] != p or m.shape[2] != 3:
            raise InputError(f"measured positions: expected shape ({p}, n, 3), got {m.shape}")
        n = m.shape[1]
        shapes = {"cycles": (np.shape(self.cycles), (n,)),
                  "commanded positions": (np.shape(self.commanded), (p, 3))}
        if self.measured_rotations is not None:
            shapes["measured orientations"] = (np.shape(self.measured_rotations), (p, n, 3, 3))
        if self.commanded_rotations is not None:
            shapes["commanded orientations"] = (np.shape(self.commanded_rotations), (p, 3, 3))
        for what, (got, want) in shapes.items():
            if got != want:
                raise InputError(f"{what}: expected shape {want}, got {got}")
        if len(set(self.labels)) != p:
            raise InputError("pose labels repeat: expected one label per pose")
        if not (np.isfinite(m).all() and np.isfinite(self.commanded).all()):
            raise InputError("positions contain NaN or infinite values")

    def __repr__(self) -> str:
        src = f" from {self.source}" if self.source else ""
        return (f"<RepeatedPoses {len(self.labels)} poses x {self.n_cycles} cycles "
                f"({self.length_unit}){src}>")

    @property
    def n_cycles(self) -> int:
        """Number of cycles n."""
        return int(np.shape(self.measured)[1])
