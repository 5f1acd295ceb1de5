"""Stewart-platform geometry files (YAML): schema, reader, writer (papers/004 Table 2).

A geometry file gives either the paper's circle parameters (papers/004 eq. 1-2)::

    name: liu2008-cmm
    kind: stewart
    length_unit: m
    angle_unit: deg
    base_radius: 0.5                  # R_b
    platform_radius: 0.225            # R_p
    base_short_edge_angle: 30         # theta_b
    platform_short_edge_angle: 30     # theta_p
    probe_offset: 0.18                # l_s
    leg_range: [0.75, 0.97]           # l_min, l_max

or six explicit joints (what a calibration writes)::

    base_joints: [[x, y, z], ...]     # 6 rows, base frame
    platform_joints: [[x, y, z], ...] # 6 rows, platform frame
    leg_offsets: [o1, ..., o6]        # optional, physical length minus reading

Bundled geometries live in ``kinecal/robots/NAME.yaml`` (with ``kind: stewart``) and are
loaded by name. Writes are atomic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinecal._files import write_text_atomic
from kinecal._yaml import read_yaml_mapping
from kinecal.errors import InputError
from kinecal.io.bundled import bundled_names, resolve_machine_file
from kinecal.io.geometry_plain import plain_geometry
from kinecal.kinematics.stewart.platform import StewartPlatform

__all__ = [
    "bundled_geometries",
    "geometry_path",
    "geometry_to_dict",
    "load_geometry",
    "save_geometry",
]

def _platform(spec) -> StewartPlatform:
    """The `StewartPlatform` of checked geometry fields `spec` (angles in radians)."""
    to_rad = np.deg2rad if spec.angle_unit == "deg" else float
    rng = (float(spec.leg_range[0]), float(spec.leg_range[1]))
    if spec.base_joints is None:
        geom = StewartPlatform.from_circles(
            float(spec.base_radius),
            float(spec.platform_radius),
            float(to_rad(spec.base_short_edge_angle)),
            float(to_rad(spec.platform_short_edge_angle)),
            spec.probe_offset,
            rng,
            spec.name,
        )
    else:
        geom = StewartPlatform(
            np.array(spec.base_joints), np.array(spec.platform_joints),
            spec.probe_offset, rng, np.zeros(6), spec.name,
        )  # fmt: skip
    if spec.leg_offsets is not None:
        geom = geom.with_parameters(
            np.concatenate([geom.parameters[:36], np.asarray(spec.leg_offsets, float)])
        )
    return geom


def _checked(data: dict, path: Path):
    """The fields of a geometry file that is not plainly valid (`plain_geometry`), checked
    by the pydantic schema, which words the error."""
    from pydantic import ValidationError

    from kinecal.io.geometry_schema import GeometrySpec

    try:
        return GeometrySpec.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(x) for x in err["loc"])
        msg = err["msg"].removeprefix("Value error, ")
        raise InputError(f"{loc + ': ' if loc else ''}{msg}", file=path) from None


def bundled_geometries() -> list[str]:
    """Names of the bundled Stewart geometries (``kind: stewart`` files in robots/)."""
    return bundled_names("geometry")


def geometry_path(name_or_path: str | Path) -> Path:
    """Path of a geometry file from a bundled name or a path; `InputError` if neither."""
    return resolve_machine_file(name_or_path, "geometry", option="GEOMETRY")


def load_geometry(name_or_path: str | Path) -> StewartPlatform:
    """Load a Stewart geometry from a bundled name (``liu2008-cmm``) or a YAML path.

    Raises
    ------
    InputError
        Unknown name, unreadable file, invalid YAML or schema violation (with the file).
    """
    path = geometry_path(name_or_path)
    data = read_yaml_mapping(path)
    spec = plain_geometry(data)
    try:
        return _platform(spec if spec is not None else _checked(data, path))
    except InputError as exc:
        raise InputError(exc.message, file=path) from None


def geometry_to_dict(geom: StewartPlatform, length_unit: str = "m") -> dict:
    """Explicit-joint description of `geom` (the form `load_geometry` reads back)."""
    return {
        "name": geom.name,
        "kind": "stewart",
        "length_unit": length_unit,
        "angle_unit": "deg",
        "base_joints": geom.base_joints.tolist(),
        "platform_joints": geom.platform_joints.tolist(),
        "leg_offsets": geom.leg_offsets.tolist(),
        "probe_offset": geom.probe_offset,
        "leg_range": list(geom.leg_range),
    }


def save_geometry(geom: StewartPlatform, path: str | Path, length_unit: str = "m") -> None:
    """Write `geom` as an explicit-joint geometry YAML, atomically (full float precision)."""
    import yaml

    text = yaml.safe_dump(geometry_to_dict(geom, length_unit), sort_keys=False)
    write_text_atomic(path, text)
