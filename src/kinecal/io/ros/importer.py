"""`import_bag`: the rows of a bag where the robot dwells.

Two passes over the bag, each streamed: the joint topic first (`kinecal.io.ros.dwell`
finds the dwells), then the measurement topics, each message added to the dwell its time
falls in (`kinecal.io.ros.accumulate`); images are chosen and written as they stream by
(`kinecal.io.ros.images`). Times are the messages' ``header.stamp`` (the bag's receive
time where a publisher left it zero). A dwell becomes a row when every requested stream
covers it; otherwise it is dropped with its reason.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.io.ros import messages as msgs
from kinecal.io.ros.accumulate import StreamAverage, TfTree
from kinecal.io.ros.bag import Bag
from kinecal.io.ros.clocks import StreamTimes, check_overlap
from kinecal.io.ros.dwell import Dwell, DwellFinder
from kinecal.io.ros.joints import JointMapper
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["BagImport", "ImportOptions", "import_bag"]

Array = NDArray[np.float64]
_PER_M = {"m": 1.0, "mm": 1000.0}
_CHUNK = 4096
_TF_TOPICS = ("/tf", "/tf_static")
#: why a JointState gave no sample (`_find_dwells`)
_UNEVEN = "with fewer or more positions than names"
_UNMATCHED = "without the model's joint names"
_NONFINITE = "with non-finite positions"
_BACKWARDS = "whose time did not increase"
_TWO_TURNS = 4 * np.pi


@dataclass
class ImportOptions:
    """What to read from a bag (the options of ``kinecal import``).

    Attributes
    ----------
    joints : str
        JointState topic.
    points, poses : str, optional
        PointStamped topic; PoseStamped or TransformStamped topic.
    tf : (str, str), optional
        Parent and child frame looked up in ``/tf`` and ``/tf_static``.
    images, camera_info : str, optional
        Image or CompressedImage topic and its CameraInfo topic.
    dwell : float
        Minimum dwell (s).
    still : float
        Joint speed tolerance (rad/s; length unit/s for prismatic joints).
    joint_names : sequence of str, optional
        The bag's name of each model joint.
    """

    joints: str
    points: str | None = None
    poses: str | None = None
    tf: tuple[str, str] | None = None
    images: str | None = None
    camera_info: str | None = None
    dwell: float = 0.3
    still: float = 0.002
    joint_names: Sequence[str] | None = None

    def __post_init__(self) -> None:
        """`InputError` for values no import can use (named by their option)."""
        if not (np.isfinite(self.dwell) and self.dwell > 0):
            raise InputError(f"expected a positive time in seconds, got {self.dwell:g}",
                             option="--dwell")
        if not (np.isfinite(self.still) and self.still > 0):
            raise InputError(f"expected a positive speed, got {self.still:g}", option="--still")
        if self.tf is not None and self.tf[0] == self.tf[1]:
            raise InputError(f"{self.tf[0]}:{self.tf[1]}: the pose of a frame in itself is the "
                             "identity: expected two frames", option="--tf")


@dataclass
class BagImport:
    """The rows of a bag (`import_bag`).

    Attributes
    ----------
    dwells, short : list of Dwell
        Every dwell, and the shorter stops (times in s from the first joint sample).
    kept : list of int
        Indices of the dwells that became rows, in order.
    dropped : list of (int, str)
        Dwell index and reason of each dropped dwell.
    q : ndarray, shape (K, n_joints)
        Joints of the rows (rad; prismatic: model length unit).
    xyz : ndarray, shape (K, 3), optional
        Averaged points (model length unit).
    poses : ndarray, shape (K, 4, 4), optional
        Averaged poses or tf lookups (model length unit).
    images : list of str
        Image file names of the rows (with ``--images``).
    camera : dict, optional
        The first CameraInfo (`kinecal.io.ros.messages.camera_info`).
    """

    dwells: list[Dwell]
    short: list[Dwell]
    kept: list[int] = field(default_factory=list)
    dropped: list[tuple[int, str]] = field(default_factory=list)
    q: Array | None = None
    xyz: Array | None = None
    poses: Array | None = None
    images: list[str] = field(default_factory=list)
    camera: dict | None = None
    samples: int = 0
    joints_how: str = ""
    skipped: int = 0


def _time(bag_ns: int, stamp: int, t0: int) -> float:
    return ((stamp if stamp > 0 else bag_ns) - t0) * 1e-9


def _check_topics(bag: Bag, opts: ImportOptions) -> dict[str, str]:
    kinds = {opts.joints: bag.check_topic(opts.joints, "--joints")}
    for opt, topic in (("--points", opts.points), ("--poses", opts.poses),
                       ("--images", opts.images), ("--camera-info", opts.camera_info)):
        if topic is not None:
            kinds[topic] = bag.check_topic(topic, opt)
    if opts.tf is not None:
        found = [t for t in _TF_TOPICS if t in bag.topics]
        if not found:
            raise InputError(f"the bag has no /tf or /tf_static topic (topics: "
                             f"{', '.join(sorted(bag.topics))})", option="--tf")
        for t in found:
            kinds[t] = bag.check_topic(t, "--tf")
    return kinds


def _find_dwells(bag: Bag, model: SerialModel, opts: ImportOptions,
                 out: dict[str, int]) -> tuple[DwellFinder, int, str]:
    """First pass: the joint stream through a `DwellFinder`; also the time origin. Samples
    left out are counted in `out` by reason."""
    mapper = JointMapper(model.n_joints, opts.joint_names, opts.joints)
    finder = DwellFinder(model.n_joints, opts.dwell, opts.still)
    scale = np.where(model.is_prismatic(), _PER_M[model.length_unit], 1.0)
    t0, ts, qs, sizes = None, [], [], None
    for _topic, kind, bag_ns, raw in bag.stream([opts.joints]):
        msg = bag.decode(raw, kind)
        names, pos = msgs.joint_state(msg)
        if len(pos) != len(names):
            out[_UNEVEN] = out.get(_UNEVEN, 0) + 1
            sizes = sizes or (len(names), len(pos))
            continue
        idx = mapper.index(names)
        if idx is None:
            out[_UNMATCHED] = out.get(_UNMATCHED, 0) + 1
            continue
        if not np.isfinite(pos[idx]).all():
            out[_NONFINITE] = out.get(_NONFINITE, 0) + 1
            continue
        stamp = msgs.stamp_ns(msg)
        t0 = (stamp if stamp > 0 else bag_ns) if t0 is None else t0
        ts.append(_time(bag_ns, stamp, t0))
        qs.append(pos[idx])
        if len(ts) == _CHUNK:
            finder.feed(np.array(ts), np.array(qs) * scale)
            ts, qs = [], []
    if t0 is None:
        raise _no_sample(opts.joints, mapper, out, sizes)
    if ts:
        finder.feed(np.array(ts), np.array(qs) * scale)
    finder.finish()
    if finder.skipped:
        out[_BACKWARDS] = finder.skipped
    return finder, t0, mapper.how


def _no_sample(topic: str, mapper: JointMapper, out: dict[str, int],
               sizes: tuple[int, int] | None) -> InputError:
    """The error when no JointState of `topic` gave a sample."""
    if out.get(_NONFINITE):
        return InputError(f"{topic}: the model's joints are not finite (NaN or inf) in every "
                          f"JointState ({out[_NONFINITE]})", option="--joints")
    if mapper.seen is None and sizes is not None:
        return InputError(f"{topic}: no JointState ({out[_UNEVEN]}) has as many positions "
                          f"as names: got {sizes[0]} names and {sizes[1]} positions",
                          option="--joints")
    if mapper.seen is None:
        return InputError(f"topic {topic} has no message", option="--joints")
    return mapper.fail()


def _warn_degrees(topic: str, model: SerialModel, dwells: list[Dwell]) -> None:
    """A warning when revolute joints dwell beyond two turns: ROS gives radians, such
    values are degrees (or encoder counts)."""
    revolute = ~model.is_prismatic()
    if not dwells or not revolute.any():
        return
    worst = float(np.abs(np.array([d.q for d in dwells])[:, revolute]).max())
    if worst > _TWO_TURNS:
        from kinecal.diagnostics import warn

        warn("ros-joint-units", f"{topic}: revolute joints dwell at up to {worst:.4g} rad "
             f"({np.degrees(worst):.4g} deg), beyond two turns: ROS gives radians; were "
             "they recorded in degrees?")


def _warn_skipped(topic: str, samples: int, skipped: dict[str, int]) -> None:
    """One warning for the joint samples left out, by reason."""
    if skipped:
        from kinecal.diagnostics import warn

        reasons = ", ".join(f"{n} {why}" for why, n in skipped.items())
        warn("ros-samples-skipped", f"{topic}: {sum(skipped.values())} JointState messages "
             f"left out ({reasons}); {samples} samples used")


def _second_pass(bag: Bag, kinds: dict, opts: ImportOptions, starts: Array, ends: Array,
                 t0: int, on_image: Callable | None,
                 bad: dict[str, list], clock: StreamTimes) -> tuple[dict, TfTree | None]:
    """Stream the measurement topics into per-dwell averages (and images); values that are
    no measurement are counted in `bad` and left out."""
    acc: dict[str, StreamAverage] = {}
    if opts.points:
        acc[opts.points] = StreamAverage(starts, ends, 3)
    if opts.poses:
        acc[opts.poses] = StreamAverage(starts, ends, 7)
    tree = TfTree(starts, ends) if opts.tf else None
    topics = [t for t in kinds if t != opts.joints]

    def dwell_of(t: float) -> int | None:
        k = int(np.searchsorted(starts, t, side="right")) - 1
        return k if k >= 0 and t <= ends[k] else None

    for topic, kind, bag_ns, raw in bag.stream(topics):
        if topic == opts.images or topic == opts.camera_info:
            on_image(topic, kind, bag_ns, raw, dwell_of)
            continue
        msg = bag.decode(raw, kind)
        if tree is not None and topic in _TF_TOPICS:
            for parent, child, stamp, pq in msgs.tf_transforms(msg):
                t = _time(bag_ns, stamp, t0)
                if topic != "/tf_static":
                    clock.add(topic, t)
                if _valid(bad, f"{topic} {parent}->{child}", pq):
                    tree.add(parent, child, dwell_of(t), t, pq, topic == "/tf_static")
                elif topic != "/tf_static":  # the edge exists, without a value
                    tree.add(parent, child, None, t, pq, False)
            continue
        v = msgs.point(msg) if topic == opts.points else msgs.pose(msg)
        t = _time(bag_ns, msgs.stamp_ns(msg), t0)
        clock.add(topic, t)
        k = dwell_of(t)
        if k is not None and _valid(bad, topic, v):
            acc[topic].add(k, t, v)
    return acc, tree


def _valid(bad: dict[str, list], what: str, v: Array) -> bool:
    """False (and counted in `bad` with its reason) for a value that is no measurement."""
    why = msgs.value_problem(v)
    if why is not None:
        bad.setdefault(what, [0, why])[0] += 1
    return why is None


def _warn_bad(bad: dict[str, list]) -> None:
    """One warning per stream whose messages were left out (`_valid`)."""
    from kinecal.diagnostics import warn

    for what, (n, why) in bad.items():
        warn("ros-bad-values", f"{what}: {n} messages left out, their values are no "
             f"measurement (first: {why}); dwells without another message are dropped")


def import_bag(path: str | Path, model: SerialModel, opts: ImportOptions,
               images: Callable | None = None) -> BagImport:
    """The dwell rows of a bag (module docstring).

    Parameters
    ----------
    path : str or Path
        The bag.
    model : SerialModel
        Gives the joint count, order (names), units.
    opts : ImportOptions
    images : ImageWriter, optional
        With ``opts.images``: writes the image of each dwell and ``camera.yaml``
        (`kinecal.io.ros.images.ImageWriter`).

    Raises
    ------
    InputError
        A missing topic or one of another type, joint names matching no model joint, a
        truncated or corrupt bag, no dwell at all.
    """
    if not isinstance(model, SerialModel):
        raise TypeError(f"model: expected a SerialModel, got {type(model).__name__}")
    if not isinstance(opts, ImportOptions):
        raise TypeError(f"opts: expected ImportOptions, got {type(opts).__name__}")
    if opts.joint_names is not None and len(opts.joint_names) != model.n_joints:
        raise InputError(f"expected {model.n_joints} names (one per model joint), got "
                         f"{len(opts.joint_names)}", option="--joint-names")
    with Bag(path) as bag:
        kinds = _check_topics(bag, opts)
        skipped: dict[str, int] = {}
        finder, t0, how = _find_dwells(bag, model, opts, skipped)
        dwells = finder.dwells
        out = BagImport(dwells, finder.short, samples=finder.samples, joints_how=how or "",
                        skipped=sum(skipped.values()))
        if not dwells:
            left = "".join(f", {n} {why} left out" for why, n in skipped.items())
            raise InputError(f"no dwell in {finder.samples} joint samples{left}: the joints "
                             f"were never still (speed below {opts.still:g}/s) for "
                             f"{opts.dwell:g} s; see --dwell and --still", file=path)
        _warn_skipped(opts.joints, finder.samples, skipped)
        _warn_degrees(opts.joints, model, dwells)
        starts = np.array([d.start for d in dwells])
        ends = np.array([d.end for d in dwells])
        acc, tree = ({}, None)
        if images is not None:
            images.begin(bag, starts, ends, t0)
        bad: dict[str, list] = {}
        clock = StreamTimes()
        if len(kinds) > 1:
            acc, tree = _second_pass(bag, kinds, opts, starts, ends, t0, images, bad, clock)
        used = {t: int(a.counts.sum()) for t, a in acc.items()}
        if tree is not None:
            used.update({t: sum(int(a.counts.sum()) for a in tree.dynamic.values())
                         for t in _TF_TOPICS})
        check_overlap(clock, opts.joints, (0.0, finder.t_last), t0, used)
        if images is not None:
            images.finish()
        _warn_bad(bad)
    _rows(out, model, opts, acc, tree, images)
    return out


def _rows(out: BagImport, model: SerialModel, opts: ImportOptions, acc: dict,
          tree: TfTree | None, images) -> None:
    """Keep the dwells every stream covers; fill `out`'s arrays."""
    per_m = _PER_M[model.length_unit]
    path = tree.path(*opts.tf) if tree is not None else None
    xyz, poses = [], []
    for k in range(len(out.dwells)):
        why, pose = None, None
        for topic, a in acc.items():
            why = why or a.problem(k, topic)
        if why is None and path is not None:
            pose, why = tree.lookup(path, k)
        if why is None and images is not None:
            why = images.problem(k)
        if why is not None:
            out.dropped.append((k, why))
            continue
        out.kept.append(k)
        if opts.points:
            xyz.append(acc[opts.points].mean(k) * per_m)
        if opts.poses:
            from kinecal.spatial import transform_from_pq

            pose = transform_from_pq(acc[opts.poses].mean(k))
        if pose is not None:
            pose = pose.copy()
            pose[:3, 3] *= per_m
            poses.append(pose)
    moving = [k + 1 for k, why in out.dropped if why.startswith("moving:")]
    if moving:
        from kinecal.diagnostics import warn

        warn("ros-dwell-moving", f"{len(moving)} of {len(out.dwells)} dwells dropped (dwell "
             f"{', '.join(map(str, moving[:5]))}{', ...' if len(moving) > 5 else ''}): the "
             "measurement moved while the joints read still; were the joint_states frozen, "
             f"or is --still ({opts.still:g}) too loose?")
    out.q = np.array([out.dwells[k].q for k in out.kept]).reshape(-1, model.n_joints)
    out.xyz = np.array(xyz).reshape(-1, 3) if opts.points else None
    out.poses = np.array(poses).reshape(-1, 4, 4) if (opts.poses or opts.tf) else None
    if images is not None:
        out.images = [images.name(k) for k in out.kept]
        out.camera = images.camera
