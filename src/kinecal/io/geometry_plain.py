"""Stewart geometry files checked without pydantic when they are plainly valid (as
`kinecal.io.model_plain` does for serial-arm model files): `plain_geometry` returns the
fields `kinecal.io.geometry_schema.GeometrySpec` would, or None for anything not plainly
valid (a number written as text, a missing or unknown key, NaN, a value out of range...),
which the caller then checks with the schema, which also words the error.
tests/io/test_geometry_plain.py checks both agree.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

from kinecal.io.model_plain import plain_number

__all__ = ["CIRCLE_KEYS", "FIELDS", "plain_geometry"]

CIRCLE_KEYS = ("base_radius", "platform_radius", "base_short_edge_angle",
               "platform_short_edge_angle")
#: the schema's fields
FIELDS = ("name", "kind", "source", "length_unit", "angle_unit", *CIRCLE_KEYS, "base_joints",
          "platform_joints", "leg_offsets", "probe_offset", "leg_range")


def _numbers(v: Any, n: int) -> list[float] | None:
    if type(v) is not list or len(v) != n:
        return None
    out = [plain_number(c) for c in v]
    return None if any(c is None for c in out) else out


def _choice(data: dict, key: str, allowed: tuple[str, ...]) -> str | None:
    v = data.get(key, allowed[0])
    return v if type(v) is str and v in allowed else None


def plain_geometry(data: dict) -> SimpleNamespace | None:
    """The checked fields of a geometry file's mapping, or None (module docstring)."""
    if set(data) - set(FIELDS):
        return None
    out: dict[str, Any] = {}
    for key in ("name", "source"):
        out[key] = data.get(key)
        if out[key] is not None and type(out[key]) is not str:
            return None
    for key, allowed in (("kind", ("stewart",)), ("length_unit", ("m", "mm")),
                         ("angle_unit", ("deg", "rad"))):
        out[key] = _choice(data, key, allowed)
        if out[key] is None:
            return None
    for key in (*CIRCLE_KEYS, "probe_offset"):
        v = data.get(key, 0.0 if key == "probe_offset" else None)
        out[key] = None if v is None else plain_number(v)
        if v is not None and out[key] is None:
            return None
    for key in ("base_joints", "platform_joints"):
        v = data.get(key)
        rows = None if v is None or type(v) is not list or len(v) != 6 else \
            [_numbers(p, 3) for p in v]
        if v is not None and (rows is None or any(r is None for r in rows)):
            return None
        out[key] = rows
    v = data.get("leg_offsets")
    out["leg_offsets"] = None if v is None else _numbers(v, 6)
    out["leg_range"] = _numbers(data.get("leg_range"), 2)
    if (v is not None and out["leg_offsets"] is None) or out["leg_range"] is None:
        return None
    return SimpleNamespace(**{k: out[k] for k in FIELDS}) if _consistent(out) else None


def _consistent(out: dict) -> bool:
    """The schema's checks of values: radii > 0, a range 0 <= l_min < l_max, either all
    circle parameters or both joint lists, short-edge angles below 120 deg."""
    lo, hi = out["leg_range"]
    if not 0.0 <= lo < hi:
        return False
    if any(out[k] is not None and not out[k] > 0 for k in CIRCLE_KEYS[:2]):
        return False
    circles = [out[k] is not None for k in CIRCLE_KEYS]
    joints = [out["base_joints"] is not None, out["platform_joints"] is not None]
    if not ((all(circles) and not any(joints)) or (all(joints) and not any(circles))):
        return False
    most = 120.0 if out["angle_unit"] == "deg" else 2.0 * math.pi / 3.0
    return all(out[k] is None or 0.0 <= out[k] < most for k in CIRCLE_KEYS[2:])
