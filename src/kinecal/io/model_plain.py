"""Model files checked without pydantic when they are plainly valid.

Importing pydantic and building the schema of `kinecal.io.model_schema` costs 0.03-0.05 s
of CPU, a third of a one-pose ``kinecal fk``. `plain_model_file` accepts a mapping only
when every value has exactly the schema's type (numbers as int or float, finite; strings;
booleans; lists of the right lengths) and then returns what the schema would:
the same fields, defaults filled in, each chain entry as the schema's ``model_dump
(exclude_none=True)``. Anything else (a number written as a string, a missing or unknown
key, NaN...) returns None: the caller then validates with the pydantic schema, which
also words the error. tests/io/test_model_plain.py checks both agree on the bundled models
and on many altered ones.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["ENTRY_FIELDS", "FILE_FIELDS", "plain_entry", "plain_model_file", "plain_number"]

_REQUIRED = object()
#: no plain answer: validate with the schema
_NO = object()

# (field, kind, default) in the schema's order; kinds: "float", "float?", "str", "str?",
# "bool", "axis", or a tuple of allowed strings
_XYZ = [("x", "float", 0.0), ("y", "float", 0.0), ("z", "float", 0.0)]
_W = [("wx", "float", 0.0), ("wy", "float", 0.0), ("wz", "float", 0.0)]
_LINKS = [("parent", "str?", None), ("child", "str?", None)]

#: the fields of `kinecal.io.model_schema`'s entry classes, by (urdf, fixed frame)
ENTRY_FIELDS: dict[tuple[bool, bool], list[tuple[str, Any, Any]]] = {
    (False, False): [("theta", "float", 0.0), ("d", "float", _REQUIRED),
                     ("a", "float", _REQUIRED), ("alpha", "float", _REQUIRED),
                     ("beta", "float?", None), ("type", ("revolute", "prismatic"), "revolute")],
    (True, False): [("name", "str", _REQUIRED),
                    ("type", ("revolute", "continuous", "prismatic"), "revolute"), *_XYZ,
                    ("roll", "float", 0.0), ("pitch", "float", 0.0), ("yaw", "float", 0.0),
                    *_W, ("offset", "float", 0.0), ("axis", "axis", (1.0, 0.0, 0.0)),
                    *_LINKS, ("effort", "float?", None), ("velocity", "float?", None)],
    (False, True): [("frame", "str", _REQUIRED), *_XYZ, ("rx", "float", 0.0),
                    ("ry", "float", 0.0), ("rz", "float", 0.0), *_W,
                    ("calibrate", "bool", False)],
    (True, True): [("frame", "str", _REQUIRED), *_XYZ, ("roll", "float", 0.0),
                   ("pitch", "float", 0.0), ("yaw", "float", 0.0), *_W,
                   ("calibrate", "bool", False), *_LINKS],
}

#: the top-level fields of `kinecal.io.model_schema.ModelFile` checked here (the
#: structured ones by `_structured`)
FILE_FIELDS = [("name", "str", _REQUIRED), ("description", "str", ""), ("source", "str", ""),
               ("convention", ("dh", "craig", "hayati", "urdf"), _REQUIRED),
               ("length_unit", ("mm", "m"), "mm"), ("angle_unit", ("deg", "rad"), _REQUIRED)]
_STRUCTURED = ("joints", "base", "tool", "markers", "joint_limits", "tolerances", "fixed",
               "joint_errors")


def plain_number(v: Any) -> float | None:
    """`v` as the schemas' float when it is an int or a finite float, else None."""
    if type(v) is float:
        return v if math.isfinite(v) else None
    if type(v) is int:
        return float(v)
    return None


def _number(v: Any) -> Any:
    out = plain_number(v)
    return _NO if out is None else out


def _value(kind: Any, v: Any) -> Any:
    if kind == "float" or (kind == "float?" and v is not None):
        return _number(v)
    if kind in ("float?", "str?") and v is None:
        return None
    if kind in ("str", "str?"):
        return v if type(v) is str else _NO
    if kind == "bool":
        return v if type(v) is bool else _NO
    if kind == "axis":
        if type(v) not in (list, tuple) or len(v) != 3:
            return _NO
        out = tuple(_number(c) for c in v)
        return _NO if _NO in out else out
    return v if type(v) is str and v in kind else _NO


def _fields(fields: list[tuple[str, Any, Any]], data: dict) -> dict | None:
    """The checked `fields` of `data` with defaults (None: not plainly valid)."""
    out = {}
    for name, kind, default in fields:
        if name not in data:
            if default is _REQUIRED:
                return None
            out[name] = default
            continue
        v = _value(kind, data[name])
        if v is _NO:
            return None
        out[name] = v
    return out


def _numbers(v: Any, lengths: tuple[int, ...]) -> list[float] | None:
    if type(v) is not list or len(v) not in lengths:
        return None
    out = [_number(c) for c in v]
    return None if _NO in out else out


def _structured(data: dict) -> dict | None:
    out: dict[str, Any] = {}
    joints = data.get("joints")
    if type(joints) is not list or not joints or any(type(j) is not dict for j in joints):
        return None
    out["joints"] = [dict(j) for j in joints]
    for key, lengths in (("base", (6, 9)), ("tool", (3, 6, 9))):
        v = data.get(key)
        out[key] = None if v is None else _numbers(v, lengths)
        if v is not None and out[key] is None:
            return None
    markers = data.get("markers")
    if markers is not None:
        if type(markers) is not dict or not markers:
            return None
        out["markers"] = {k: _numbers(p, (3,)) for k, p in markers.items()}
        if any(type(k) is not str or p is None for k, p in out["markers"].items()):
            return None
    else:
        out["markers"] = None
    limits = data.get("joint_limits")
    if limits is not None:
        rows = [_numbers(r, (2,)) if type(r) is list else None for r in limits] \
            if type(limits) is list else [None]
        if any(r is None for r in rows):
            return None
        out["joint_limits"] = [tuple(r) for r in rows]
    else:
        out["joint_limits"] = None
    tol = data.get("tolerances", {})
    if type(tol) is not dict or set(tol) - {"length", "angle"}:
        return None
    out["tolerances"] = {k: _number(tol.get(k, 1.0)) for k in ("length", "angle")}
    if any(v is _NO or not v > 0 for v in out["tolerances"].values()):
        return None
    fixed = data.get("fixed", [])
    if type(fixed) is not list or any(type(f) is not str for f in fixed):
        return None
    out["fixed"] = list(fixed)
    je = data.get("joint_errors")
    if je is not None and type(je) is not dict:
        return None
    out["joint_errors"] = None if je is None else dict(je)
    return out


def plain_entry(convention: str, entry: dict) -> dict | None:
    """The schema's ``model_dump(exclude_none=True)`` of one chain entry, or None when
    it is not plainly valid (unknown key, a value of another type)."""
    fields = ENTRY_FIELDS[(convention == "urdf", "frame" in entry)]
    if set(entry) - {name for name, _, _ in fields}:
        return None
    out = _fields(fields, entry)
    return None if out is None else {k: v for k, v in out.items() if v is not None}


def plain_model_file(data: dict) -> dict | None:
    """The checked fields of a model file's mapping (`kinecal.io.model_schema.ModelFile`'s
    attributes; ``tolerances`` as a mapping), or None when not plainly valid."""
    if set(data) - {name for name, _, _ in FILE_FIELDS} - set(_STRUCTURED):
        return None
    out = _fields(FILE_FIELDS, data)
    rest = None if out is None else _structured(data)
    return None if rest is None else {**out, **rest}
