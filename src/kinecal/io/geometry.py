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
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator, model_validator

from kinecal._files import write_text_atomic
from kinecal._yaml import read_yaml_mapping
from kinecal.errors import InputError
from kinecal.io.bundled import bundled_names, resolve_machine_file
from kinecal.kinematics.stewart.platform import StewartPlatform

__all__ = [
    "GeometrySpec",
    "bundled_geometries",
    "geometry_path",
    "geometry_to_dict",
    "load_geometry",
    "save_geometry",
]

_CIRCLE_KEYS = (
    "base_radius",
    "platform_radius",
    "base_short_edge_angle",
    "platform_short_edge_angle",
)


class GeometrySpec(BaseModel):
    """Schema of a Stewart geometry file (lengths in `length_unit`, angles in `angle_unit`)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    name: str | None = None
    kind: Literal["stewart"] = "stewart"
    source: str | None = None
    length_unit: Literal["m", "mm"] = "m"
    angle_unit: Literal["deg", "rad"] = "deg"
    base_radius: float | None = None
    platform_radius: float | None = None
    base_short_edge_angle: float | None = None
    platform_short_edge_angle: float | None = None
    base_joints: list[list[float]] | None = None
    platform_joints: list[list[float]] | None = None
    leg_offsets: list[float] | None = None
    probe_offset: float = 0.0
    leg_range: list[float]

    @field_validator("base_joints", "platform_joints")
    @classmethod
    def _six_points(cls, v: list[list[float]] | None) -> list[list[float]] | None:
        if v is not None and (len(v) != 6 or any(len(p) != 3 for p in v)):
            raise ValueError("expected 6 points [x, y, z]")
        return v

    @field_validator("leg_offsets")
    @classmethod
    def _six_offsets(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and len(v) != 6:
            raise ValueError("expected 6 leg offsets")
        return v

    @field_validator("base_radius", "platform_radius")
    @classmethod
    def _radius(cls, v: float | None) -> float | None:
        if v is not None and not v > 0:
            raise ValueError(f"expected a radius > 0, got {v:g}")
        return v

    @field_validator("leg_range")
    @classmethod
    def _range(cls, v: list[float]) -> list[float]:
        if len(v) != 2 or not (0.0 <= v[0] < v[1]):
            raise ValueError("expected [l_min, l_max] with 0 <= l_min < l_max")
        return v

    @model_validator(mode="after")
    def _one_description(self) -> GeometrySpec:
        circles = [getattr(self, k) is not None for k in _CIRCLE_KEYS]
        joints = [self.base_joints is not None, self.platform_joints is not None]
        if any(circles) and any(joints):
            raise ValueError("give either the circle parameters or explicit joints, not both")
        if any(joints) and not all(joints):
            raise ValueError("base_joints and platform_joints go together")
        if not any(joints) and not all(circles):
            missing = [k for k, c in zip(_CIRCLE_KEYS, circles, strict=True) if not c]
            raise ValueError(f"missing {', '.join(missing)} (or give explicit joints)")
        most = 120.0 if self.angle_unit == "deg" else 2.0 * np.pi / 3.0
        for key in _CIRCLE_KEYS[2:]:  # a joint pair's short edge spans less than 120 deg
            v = getattr(self, key)
            if v is not None and not 0.0 <= v < most:
                raise ValueError(f"{key}: expected an angle in [0, {most:.4g}) "
                                 f"{self.angle_unit}, got {v:g}")
        return self

    def to_platform(self) -> StewartPlatform:
        """Build the `StewartPlatform` (angles converted to radians)."""
        to_rad = np.deg2rad if self.angle_unit == "deg" else float
        rng = (float(self.leg_range[0]), float(self.leg_range[1]))
        if self.base_joints is None:
            geom = StewartPlatform.from_circles(
                float(self.base_radius),
                float(self.platform_radius),
                float(to_rad(self.base_short_edge_angle)),
                float(to_rad(self.platform_short_edge_angle)),
                self.probe_offset,
                rng,
                self.name,
            )
        else:
            geom = StewartPlatform(
                np.array(self.base_joints), np.array(self.platform_joints),
                self.probe_offset, rng, np.zeros(6), self.name,
            )  # fmt: skip
        if self.leg_offsets is not None:
            geom = geom.with_parameters(
                np.concatenate([geom.parameters[:36], np.asarray(self.leg_offsets, float)])
            )
        return geom


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
    try:
        spec = GeometrySpec.model_validate(data)
        return spec.to_platform()
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(x) for x in err["loc"])
        msg = err["msg"].removeprefix("Value error, ")
        raise InputError(f"{loc + ': ' if loc else ''}{msg}", file=path) from None
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
    text = yaml.safe_dump(geometry_to_dict(geom, length_unit), sort_keys=False)
    write_text_atomic(path, text)
