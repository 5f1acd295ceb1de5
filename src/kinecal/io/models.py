"""Serial-arm model files (YAML): schema, `load_model`, `save_model`.

A model file (see ``docs/file-formats.md``)::

    name: irb120
    convention: hayati            # dh | craig | hayati | urdf
    length_unit: mm
    angle_unit: deg               # deg | rad: every angle in this file
    joints:
      - {theta: 0, d: 290, a: 0, alpha: -90}
      - {theta: -90, d: 0, a: 270, alpha: 0, beta: 0}
      - {frame: bracket, x: 0, y: 0, z: 50, rx: 0, ry: 0, rz: 90}   # a fixed frame
      - {theta: 0, d: 0, a: 0, alpha: 0, type: prismatic}            # d is the joint
    base: [x, y, z, rx, ry, rz]   # optional: robot base in the measurement frame
    tool: [x, y, z]               # optional: tool point in the flange frame (or a frame)
    markers: {A: [x, y, z], B: [x, y, z]}   # or several tool points, one per marker
    joint_limits: [[-165, 165], ...]   # optional; prismatic joints in the length unit
    tolerances: {length: 0.25, angle: 0.05}
    fixed: [tool.x]               # optional: parameters held at nominal by default
    joint_errors: {compliance: all, harmonics: 2}  # optional, kinecal.io.joint_errors_file

A ``urdf`` model's joints are URDF joints: ``{name, type: revolute|continuous|prismatic,
x, y, z, roll, pitch, yaw, offset, axis: [ax, ay, az]}`` (optional ``parent``/``child``
link names, and ``effort``/``velocity`` limits in URDF units, kept for URDF export), fixed
frames ``{frame, x, y, z, roll, pitch, yaw}``. A fixed frame is held at
nominal unless it says ``calibrate: true``. Origins (urdf joints, fixed frames) may carry
a calibrated local rotation error ``wx, wy, wz`` composed after their nominal
roll-pitch-yaw (`kinecal.kinematics.serial.motions.origin_motions`); absent means zero.
Likewise the base and a tool frame: 6 values (the nominal pose) or 9, the last three the
local rotation error ``wx, wy, wz`` (what the parameters ``base.rx .. base.rz``,
``tool.rx .. tool.rz`` hold; `kinecal.kinematics.serial.chain`).

Bundled models live in ``kinecal/robots/NAME.yaml`` and are loaded by name; a ``.urdf``
path is read by `kinecal.io.urdf.load_urdf`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from kinecal._files import write_text_atomic
from kinecal._yaml import read_yaml_mapping
from kinecal.errors import InputError
from kinecal.io.bundled import bundled_names, resolve_machine_file
from kinecal.io.model_plain import plain_entry, plain_model_file
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["bundled_models", "check_model_file_name", "is_urdf_path", "load_model",
           "model_from_mapping", "model_path", "read_yaml", "save_model"]


#: angle-valued keys of chain entries (a urdf joint's offset only when it rotates)
_ANGLE_KEYS = frozenset(("theta", "alpha", "beta", "rx", "ry", "rz", "roll", "pitch", "yaw",
                         "wx", "wy", "wz"))
#: an origin's local rotation error (kinecal.kinematics.serial.motions.origin_motions)
_LOCAL_KEYS = ("wx", "wy", "wz")


def _angle_keys(entry: dict) -> frozenset[str]:
    if "name" in entry and entry.get("type") != "prismatic":
        return _ANGLE_KEYS | {"offset"}
    return _ANGLE_KEYS


def _convert_entry(entry: dict, scale: float) -> dict:
    """`entry` with its angles multiplied by `scale` (non-numeric keys kept)."""
    keys = _angle_keys(entry)
    return {k: (float(v) * scale if k in keys else v) for k, v in entry.items()}


def bundled_models() -> list[str]:
    """Names of the bundled serial-arm models."""
    return bundled_names("model")


def model_path(name_or_path: str | Path) -> Path:
    """Path of a model file given a bundled name or a path; `InputError` if neither."""
    return resolve_machine_file(name_or_path, "model")


def read_yaml(path: Path) -> dict:
    """Read a YAML mapping; `InputError` with the file (and line) when unreadable."""
    return read_yaml_mapping(path)


def _validation_message(exc: Any) -> str:
    err = exc.errors()[0]
    loc = ".".join(str(x) for x in err["loc"])
    return f"{loc}: {err['msg']}"


def _is_xml(path: str | Path) -> bool:
    """True for a regular file that starts like XML (a URDF saved as ``robot.xml``)."""
    try:
        if not Path(path).is_file():
            return False
        with open(path, "rb") as fh:
            head = fh.read(256)
    except (OSError, ValueError):
        return False
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<")


def is_urdf_path(path: str | Path | None) -> bool:
    """True for a path `load_model` reads as a URDF: a ``.urdf`` or ``.xacro`` name, or a
    file that starts like XML (``robot.xml``)."""
    if path is None:
        return False
    return str(path).lower().endswith((".urdf", ".xacro")) or _is_xml(path)


def load_model(name_or_path: str | Path, *, base_link: str | None = None,
               tip_link: str | None = None) -> SerialModel:
    """Load a serial-arm model from a bundled name (``irb120``), a YAML path or a URDF.

    Angles are converted to radians; lengths stay in the file's unit. A ``.urdf`` path is
    read by `kinecal.io.urdf.load_urdf` (chain from `base_link` to `tip_link`), and so is
    a file of another suffix that starts like XML (``robot.xml``).

    Raises
    ------
    InputError
        Unknown name, unreadable file, or a schema violation (named key and reason).
    """
    if is_urdf_path(name_or_path):
        from kinecal.io.urdf import load_urdf

        return load_urdf(name_or_path, base_link=base_link, tip_link=tip_link)
    for option, value in (("--base-link", base_link), ("--tip-link", tip_link)):
        if value is not None:
            raise InputError(f"{option} applies to URDF models only", option=option)
    path = model_path(name_or_path)
    data = read_yaml(path)
    if data.get("kind") == "system":
        raise InputError("a system file (kind: system): load it with kinecal.io.systems."
                         "load_system (the commands that take systems read it as MODEL)",
                         file=path)
    return model_from_mapping(data, path)


def model_from_mapping(data: dict, path: str | Path) -> SerialModel:
    """The model of a model file's mapping `data` (`path`: where it came from, for
    messages); `InputError` on a schema violation."""
    if isinstance(data.get("markers"), dict):  # YAML reads marker names 1, 2, 3 as numbers
        data["markers"] = {str(k): v for k, v in data["markers"].items()}
    spec = _checked_file(data, path)
    scale = np.pi / 180.0 if spec.angle_unit == "deg" else 1.0
    joints = []
    for k, raw in enumerate(spec.joints):
        values = plain_entry(spec.convention, raw) if isinstance(raw, dict) else None
        if values is None:
            values = _checked_entry(spec.convention, raw, k, path)
        if "beta" in values and spec.convention != "hayati":
            raise InputError(
                "invalid model file: beta is only allowed with convention hayati", file=path
            )
        if values.get("type") == "revolute" and "frame" not in values and \
                spec.convention != "urdf":
            del values["type"]  # the default
        if not values.get("calibrate", True):
            del values["calibrate"]
        if "axis" in values:
            values["axis"] = list(values["axis"])
        joints.append(_convert_entry(values, scale))
    base = None if spec.base is None else np.r_[spec.base[:3], np.asarray(spec.base[3:]) * scale]
    tool = None
    if spec.tool is not None:
        tool = np.r_[spec.tool[:3], np.asarray(spec.tool[3:]) * scale]
    n = sum("frame" not in j for j in joints)
    limits = None
    if spec.joint_limits is not None:
        limits = np.asarray(spec.joint_limits, dtype=float)
        if limits.shape[0] != n:
            raise InputError(
                f"invalid model file: joint_limits has {limits.shape[0]} rows, expected {n} "
                "(one per moving joint)", file=path)
        prismatic = np.array([j.get("type") == "prismatic" for j in joints if "frame" not in j])
        limits = limits * np.where(prismatic, 1.0, scale)[:, None]
    try:
        model = SerialModel(
            name=spec.name, convention=spec.convention, joints=joints, base=base, tool=tool,
            length_unit=spec.length_unit, angle_unit=spec.angle_unit, joint_limits=limits,
            tolerances={"length": spec.tolerances["length"],
                        "angle": spec.tolerances["angle"] * scale},
            fixed=tuple(spec.fixed) if spec.joint_errors is None else (),
            description=spec.description, markers=spec.markers,
        )
        if spec.joint_errors is not None:  # coefficients may be named in `fixed`
            from kinecal.io.joint_errors_file import joint_errors_from_file

            je = joint_errors_from_file(model, spec.joint_errors, scale)
            model = dataclasses.replace(model, fixed=tuple(spec.fixed), joint_errors=je)
        return model
    except InputError as exc:
        raise InputError(f"invalid model file: {exc.message}", file=path) from None


def _checked_file(data: dict, path: str | Path) -> SimpleNamespace:
    """The checked top-level fields of a model file (`kinecal.io.model_plain`, else the
    pydantic schema, which words the error)."""
    plain = plain_model_file(data)
    if plain is not None:
        return SimpleNamespace(**plain)
    from pydantic import ValidationError

    from kinecal.io.model_schema import ModelFile

    try:
        spec = ModelFile.model_validate(data)
    except ValidationError as exc:
        raise InputError(f"invalid model file: {_validation_message(exc)}", file=path) from None
    fields = dict(spec)
    fields["tolerances"] = dict(spec.tolerances)
    return SimpleNamespace(**fields)


def _checked_entry(convention: str, raw: Any, k: int, path: str | Path) -> dict:
    """Chain entry `k` checked by the pydantic schema (`model_dump(exclude_none=True)`)."""
    from pydantic import ValidationError

    from kinecal.io.model_schema import entry_spec

    try:
        entry = entry_spec(convention, raw).model_validate(raw)
    except ValidationError as exc:
        raise InputError(f"invalid model file: joints.{k}.{_validation_message(exc)}",
                         file=path) from None
    return entry.model_dump(exclude_none=True)


def model_to_dict(model: SerialModel, angle_unit: str = "deg") -> dict:
    """The model-file mapping of `model` (angles in `angle_unit`)."""
    s = 180.0 / np.pi if angle_unit == "deg" else 1.0
    joints = []
    for j in model.joints:
        entry = _convert_entry(dict(j), s)
        for key in _LOCAL_KEYS:  # written only where an origin's rotation error is non-zero
            if entry.get(key) == 0.0:
                del entry[key]
        if "axis" in entry:
            entry["axis"] = [float(v) for v in entry["axis"]]
        joints.append(entry)
    data: dict = {
        "name": model.name,
        "description": model.description,
        "convention": model.convention,
        "length_unit": model.length_unit,
        "angle_unit": angle_unit,
        "joints": joints,
    }
    if model.base is not None:
        b = np.asarray(model.base, dtype=float)
        data["base"] = [float(x) for x in np.r_[b[:3], b[3:] * s]]
    if model.tool is not None:
        t = np.asarray(model.tool, dtype=float)
        data["tool"] = [float(x) for x in np.r_[t[:3], t[3:] * s]]
    if model.markers:
        data["markers"] = {str(n): [float(v) for v in p] for n, p in model.markers.items()}
    to_file = 1.0 / model.joint_scale(angle_unit)
    data["joint_limits"] = [[float(lo * f), float(hi * f)]
                            for (lo, hi), f in zip(model.joint_limits, to_file, strict=True)]
    tol = model.tolerances or {}
    data["tolerances"] = {"length": float(tol["length"]), "angle": float(tol["angle"] * s)}
    if model.fixed:
        data["fixed"] = sorted(model.fixed)
    if model.joint_errors is not None:
        from kinecal.io.joint_errors_file import joint_errors_to_file

        data["joint_errors"] = joint_errors_to_file(model, s)
    return data


def check_model_file_name(path: str | Path, option: str | None = None) -> None:
    """Refuse a model file (YAML) named ``.urdf`` or ``.xacro``: `load_model` would read it
    back as a URDF and fail on the YAML (URDF output: ``kinecal export --format urdf``)."""
    if str(path).lower().endswith((".urdf", ".xacro")):
        raise InputError(f"{Path(path).name}: a kinecal model file (YAML) named like a URDF "
                         "would be read back as a URDF: name it .yaml (for a calibrated "
                         "URDF: kinecal export RESULT.json --nominal MODEL --out FILE.urdf)",
                         option=option)


def save_model(model: SerialModel, path: str | Path, angle_unit: str | None = None) -> None:
    """Write `model` as a model file that `load_model` reads back (atomic write).

    Angles are written in `angle_unit` (default: the model's own file unit).

    Raises
    ------
    InputError
        `path` is named like a URDF (`check_model_file_name`).
    """
    check_model_file_name(path)
    angle_unit = angle_unit or model.angle_unit
    import yaml

    text = yaml.safe_dump(model_to_dict(model, angle_unit), sort_keys=False, width=100)
    write_text_atomic(path, text)
