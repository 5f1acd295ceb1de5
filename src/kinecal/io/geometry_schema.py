"""The pydantic schema of Stewart geometry files (`kinecal.io.geometry`), used when a file
is not plainly valid (`kinecal.io.geometry_plain`): it words the error."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, field_validator, model_validator

from kinecal.io.geometry_plain import CIRCLE_KEYS as _CIRCLE_KEYS

__all__ = ["GeometrySpec"]


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
