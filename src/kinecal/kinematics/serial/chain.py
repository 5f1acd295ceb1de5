"""A serial chain's entries turned into its elementary motions and named parameters.

A chain is a list of entries (dicts), in order from the base to the flange:

* a moving joint of the model's convention (``theta, d, a, alpha[, beta]`` for the D-H
  family, ``name, x, y, z, roll, pitch, yaw, wx, wy, wz, offset, axis`` for urdf),
  optionally ``type: prismatic`` (urdf also ``continuous``);
* a fixed frame ``{frame: NAME, x, y, z, rx, ry, rz, wx, wy, wz}`` (urdf: ``roll, pitch,
  yaw`` for ``rx, ry, rz``) with an optional ``calibrate: true``; its parameters are
  ``NAME.x ... NAME.wx`` and are held at nominal unless ``calibrate`` is true.

Origins (urdf joints, fixed frames) hold their nominal roll-pitch-yaw and calibrate the
local rotation error ``wx, wy, wz`` composed after it
(`kinecal.kinematics.serial.motions.origin_motions`): identifiability never depends on the
nominal angles.

The base frame (``base.x ... base.rz``) comes first, the tool (``tool.x, tool.y, tool.z``
and optionally ``tool.rx, tool.ry, tool.rz``) last; a model with several markers has
instead one tool point per marker, ``tool.NAME.x, tool.NAME.y, tool.NAME.z``
(`kinecal.kinematics.serial.markers`). The base and a tool frame are parametrised locally
about their nominal orientation (`kinecal.kinematics.serial.motions.local_pose_motions`):
``base.x, base.y, base.z`` are the base origin, ``base.rx, base.ry, base.rz`` the small
rotation after the nominal roll-pitch-yaw (held as constants), likewise for the tool.
A frame is given as 6 values ``x, y, z, rx, ry, rz`` (the nominal pose; the local error
zero) or 9, ``x, y, z, rx, ry, rz, wx, wy, wz`` with the local error (a calibrated model);
a tool point as 3.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from kinecal.errors import InputError
from kinecal.kinematics.serial.markers import check_markers, marker_parameter_names
from kinecal.kinematics.serial.motions import (
    CONTINUOUS,
    CONVENTIONS,
    FRAME_KEYS,
    PRISMATIC,
    REVOLUTE,
    RXYZ,
    TRANSLATION,
    Motion,
    frame_motions,
    local_pose_motions,
    pose_motions,
)

__all__ = ["BASE_NAMES", "MAX_ENTRIES", "MAX_JOINTS", "TOOL_NAMES", "Chain", "build_chain",
           "chain_entries", "check_chain_size", "frame_list"]

BASE_NAMES = ("base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz")
TOOL_NAMES = ("tool.x", "tool.y", "tool.z", "tool.rx", "tool.ry", "tool.rz")
_RESERVED = ("base", "tool")
#: largest length (model's unit) a chain accepts: 1000 km in mm, beyond any machine in m;
#: an origin of 1e300 let FK run but overflowed the Jacobian's squares (NaN everywhere)
MAX_LENGTH = 1e9
#: most moving joints, and chain entries (joints and fixed frames), of one model: far
#: beyond any serial arm (six or seven joints; hyper-redundant snakes a few dozen) and what
#: an identifiability analysis covers in seconds (100 joints: 4 s); a 1000-joint chain took
#: minutes and a 3000-joint one ran out of memory
MAX_JOINTS = 100
MAX_ENTRIES = 400


@dataclass(frozen=True)
class Chain:
    """Motions and parameters of a serial chain (see `build_chain`).

    Attributes
    ----------
    motions : tuple of Motion
        Every elementary motion, base first, tool last.
    owners : tuple
        Per motion: the index of its chain entry, or ``"base"`` / ``"tool"``.
    names : tuple of str
        The parameter vector: chain parameters in motion order, then base, then tool.
    values : dict
        Nominal value of every parameter (length unit, rad).
    kinds : tuple of str
        ``"revolute"`` or ``"prismatic"`` per moving joint.
    frozen : frozenset of str
        Parameters of fixed frames that are not calibrated by default.
    markers : tuple of str
        Marker names (several tool points), empty for a single tool point.
    base_rpy, tool_rpy : tuple of 3 floats
        The nominal roll-pitch-yaw (rad) of the base and of the tool frame: the constants
        their local rotation errors follow (zeros for a tool point).
    """

    motions: tuple[Motion, ...]
    owners: tuple
    names: tuple[str, ...]
    values: dict
    kinds: tuple[str, ...]
    frozen: frozenset
    markers: tuple[str, ...] = ()
    base_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tool_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _check_name(name: object, what: str) -> str:
    """A joint or frame name: any text a URDF attribute holds (spaces and quotes too: CSV
    headers quote them), except commas (they separate the names of ``--free``), control
    characters and spaces at either end (CSV readers strip them)."""
    if not isinstance(name, str) or not name or name != name.strip() or "," in name \
            or any(ord(c) < 32 or c == "\x7f" for c in name):
        raise InputError(f"{what} name {name!r}: expected a non-empty name without commas, "
                         "control characters or spaces at either end")
    if name in _RESERVED:
        raise InputError(f"{what} name {name!r} is reserved for the base and tool frames")
    return name


def _value(entry: Mapping, key: str, where: str, default: float | None) -> float:
    if key not in entry:
        if default is None:
            raise InputError(f"{where}: missing {key!r}")
        return default
    try:
        v = float(entry[key])
    except (TypeError, ValueError):
        raise InputError(f"{where}: {key}: expected a number, got {entry[key]!r}") from None
    if not np.isfinite(v):
        raise InputError(f"{where}: {key}: expected a finite number, got {v}")
    return v


def build_chain(convention: str, entries: Sequence[Mapping], base: ArrayLike | None,
                tool: ArrayLike | None, markers: Mapping | None = None) -> Chain:
    """Motions, parameter names and nominal values of a chain.

    Parameters
    ----------
    convention : {"dh", "craig", "hayati", "urdf"}
        The moving joints' convention.
    entries : sequence of dict
        Joints and fixed frames, base to flange (module docstring); lengths in the model's
        unit, angles in rad.
    base : array_like, shape (6,) or (9,), or None
        Base frame x, y, z, rx, ry, rz and optionally its local rotation error wx, wy, wz
        (None: zeros; module docstring).
    tool : array_like, shape (3,), (6,) or (9,), or None
        Tool point, or frame as the base (None: the flange origin).
    markers : mapping of str to (3,), optional
        Several tool points, one per marker (instead of `tool`); the tool translations'
        values are then per pose (`kinecal.kinematics.serial.markers`).

    Raises
    ------
    InputError
        Unknown convention, missing or non-finite values, bad names, duplicate parameters.
    """
    if convention not in CONVENTIONS:
        raise InputError(
            f"unknown convention {convention!r}; expected one of {', '.join(CONVENTIONS)}")
    make = CONVENTIONS[convention]
    check_chain_size(len(entries), sum(isinstance(e, Mapping) and "frame" not in e
                                       for e in entries))
    values: dict[str, float] = dict.fromkeys(BASE_NAMES, 0.0)
    b = _frame_values("base", np.zeros(6) if base is None else base, (6, 9))
    base_rpy = tuple(b[3:6])
    values.update(zip(BASE_NAMES, [*b[:3], *b[6:9]], strict=False))
    motions: list[Motion] = local_pose_motions("base", base_rpy)
    owners: list = ["base"] * len(motions)
    kinds: list[str] = []
    frozen: set[str] = set()
    chain_names: list[str] = []
    for e, entry in enumerate(entries):
        if not isinstance(entry, Mapping):
            raise InputError(f"joints[{e}]: expected a mapping, got {type(entry).__name__}")
        if "frame" in entry:
            name = _check_name(entry["frame"], "frame")
            where = f"frame {name}"
            em = frame_motions(name, FRAME_KEYS[convention])
            default: float | None = 0.0
            if not entry.get("calibrate", False):
                frozen.update(m.name for m in em)
        else:
            i = len(kinds) + 1
            if convention == "urdf":
                _check_name(entry.get("name"), "joint")
            try:
                em = make(i, entry)
            except InputError as exc:
                msg = exc.message
                raise InputError(msg if msg.startswith("joint") else f"joint {i}: {msg}"
                                 ) from None
            where = f"joint {entry.get('name', i)}"
            default = 0.0 if convention == "urdf" else None
            kind = entry.get("type", REVOLUTE)
            kinds.append(PRISMATIC if kind == PRISMATIC else REVOLUTE)
        frozen.update(m.name for m in em if m.held)  # nominal rpy: the error is local
        for m in em:
            if m.name in values:
                raise InputError(f"{where}: parameter {m.name!r} appears twice in the chain")
            values[m.name] = _value(entry, m.key, where, default)
            chain_names.append(m.name)
        motions += em
        owners += [e] * len(em)
    if not kinds:
        raise InputError("a model needs at least one moving joint")
    tool_rpy = (0.0, 0.0, 0.0)
    if markers is not None:
        if tool is not None:
            raise InputError("give either tool (one tool point) or markers (several), not both")
        points = check_markers(markers)
        tm = pose_motions(f"tool.{next(iter(points))}", RXYZ)[:3]
        tool_names = [n for name in points for n in marker_parameter_names(name)]
        values.update(zip(tool_names, np.concatenate(list(points.values())).tolist(),
                          strict=True))
    else:
        t = _frame_values("tool", np.zeros(3) if tool is None else tool, (3, 6, 9))
        tool_rpy = (0.0, 0.0, 0.0) if len(t) == 3 else tuple(t[3:6])
        tm = pose_motions("tool", RXYZ)[:3]
        if len(t) > 3:
            tm += local_pose_motions("tool", tool_rpy, translation=False)
        tool_names = list(TOOL_NAMES[: 3 if len(t) == 3 else 6])
        values.update(zip(TOOL_NAMES, [*t[:3], *t[6:9]], strict=False))
        if len(t) == 6:
            values.update(dict.fromkeys(TOOL_NAMES[3:], 0.0))
    motions += tm
    owners += ["tool"] * len(tm)
    names = (*chain_names, *BASE_NAMES, *tool_names)
    _check_lengths(values, [m.name for m in motions if m.kind == TRANSLATION]
                   + [n for n in tool_names if n not in TOOL_NAMES[3:]])
    duplicate = sorted(set(chain_names) & set(tool_names))
    if duplicate:
        raise InputError(f"parameter {duplicate[0]!r} appears twice in the chain")
    return Chain(tuple(motions), tuple(owners), names, values, tuple(kinds), frozenset(frozen),
                 tuple(points) if markers is not None else (), base_rpy, tool_rpy)


def _frame_values(what: str, values: ArrayLike, sizes: tuple[int, ...]) -> list[float]:
    """A base or tool given as 3 (point), 6 (pose) or 9 values (pose and local rotation
    error), checked finite; as a list of floats."""
    try:
        v = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        raise InputError(f"{what}: expected numbers, got {values!r}") from None
    forms = {3: "3 (x, y, z)", 6: "6 (x, y, z, rx, ry, rz)",
             9: "9 (x, y, z, rx, ry, rz, wx, wy, wz)"}
    if v.size not in sizes:
        raise InputError(f"{what}: expected {' or '.join(forms[n] for n in sizes)} values, "
                         f"got {v.size}")
    if not np.isfinite(v).all():
        raise InputError(f"{what}: expected finite numbers, got {v.tolist()}")
    return v.tolist()


def frame_list(values: Sequence[float], rpy: Sequence[float]) -> list[float]:
    """A base or tool frame as a model keeps it: ``x, y, z`` and the nominal `rpy`, then
    the local rotation error where it is not zero (6 or 9 values; module docstring).

    `values` are the frame's six parameter values (origin, local error)."""
    v = [float(x) for x in values]
    out = [*v[:3], *(float(a) for a in rpy)]
    return out + v[3:6] if any(v[3:6]) else out


def check_chain_size(entries: int, joints: int, where: str = "") -> None:
    """Refuse a chain of more than `MAX_ENTRIES` entries or `MAX_JOINTS` moving joints
    (`where`: what the chain is, for the message)."""
    if joints > MAX_JOINTS or entries > MAX_ENTRIES:
        raise InputError(f"{where}{joints} moving joints and {entries - joints} fixed frames "
                         f"in one chain: expected at most {MAX_JOINTS} moving joints and "
                         f"{MAX_ENTRIES} entries (no serial arm is that long; choose the "
                         "chain's ends)")


def _check_lengths(values: Mapping[str, float], lengths: Sequence[str]) -> None:
    """Every length finite and within `MAX_LENGTH` (a unit or exponent typo otherwise
    overflows the identification Jacobian far from the file that caused it)."""
    for name in lengths:
        v = values[name]
        if not np.isfinite(v) or abs(v) > MAX_LENGTH:
            raise InputError(f"{name} = {v:g} length units: expected a finite length of at "
                             f"most {MAX_LENGTH:g} in size (no machine is that large; check "
                             "the number and the length unit)")


def chain_entries(chain: Chain, entries: Sequence[Mapping], values: Mapping[str, float]
                  ) -> list[dict]:
    """Copies of `entries` whose parameter keys hold `values` (by parameter name)."""
    out = [dict(entry) for entry in entries]
    for m, owner in zip(chain.motions, chain.owners, strict=True):
        if isinstance(owner, int):
            out[owner][m.key] = float(values[m.name])
    return out


def is_continuous(entry: Mapping) -> bool:
    """True for a URDF ``continuous`` joint (a revolute joint without limits)."""
    return entry.get("type") == CONTINUOUS
