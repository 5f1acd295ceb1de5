"""The schema of serial-arm model files (pydantic): D-H family joints, URDF joints, fixed
frames, tolerances and the file itself; unknown keys and NaN/inf are refused (exit 2).
The file format is described in `kinecal.io.models` and docs/file-formats.md.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, field_validator

__all__ = ["FrameSpec", "JointSpec", "ModelFile", "Tolerances", "URDFFrameSpec",
           "URDFJointSpec", "entry_spec"]


_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False)  # NaN/inf: exit 2


class JointSpec(BaseModel):
    """One D-H-family joint (dh, craig, hayati): length unit, angle unit of the file."""

    model_config = _STRICT
    theta: float = 0.0
    d: float
    a: float
    alpha: float
    beta: float | None = None
    type: Literal["revolute", "prismatic"] = "revolute"


class URDFJointSpec(BaseModel):
    """One joint of a ``urdf`` model: origin, axis, offset (added to the reading)."""

    model_config = _STRICT
    name: str
    type: Literal["revolute", "continuous", "prismatic"] = "revolute"
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    wx: float = 0.0
    wy: float = 0.0
    wz: float = 0.0
    offset: float = 0.0
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    parent: str | None = None
    child: str | None = None
    effort: float | None = None
    velocity: float | None = None


class FrameSpec(BaseModel):
    """A fixed frame between joints (dh, craig, hayati): x, y, z, rx, ry, rz."""

    model_config = _STRICT
    frame: str
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    rx: float = 0.0
    ry: float = 0.0
    rz: float = 0.0
    wx: float = 0.0
    wy: float = 0.0
    wz: float = 0.0
    calibrate: bool = False


class URDFFrameSpec(BaseModel):
    """A fixed frame of a ``urdf`` model (a URDF fixed joint): x, y, z, roll, pitch, yaw."""

    model_config = _STRICT
    frame: str
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    wx: float = 0.0
    wy: float = 0.0
    wz: float = 0.0
    calibrate: bool = False
    parent: str | None = None
    child: str | None = None


class Tolerances(BaseModel):
    """Half-widths of the metaheuristics' search box around nominal."""

    model_config = _STRICT
    length: float = 1.0
    angle: float = 1.0

    @field_validator("length", "angle")
    @classmethod
    def _positive(cls, v: float) -> float:
        if not v > 0:
            raise ValueError("must be > 0")
        return v


class ModelFile(BaseModel):
    """Schema of a serial-arm model file (entries of `joints` checked by `entry_spec`)."""

    model_config = _STRICT
    name: str
    description: str = ""
    source: str = ""
    convention: Literal["dh", "craig", "hayati", "urdf"]
    length_unit: Literal["mm", "m"] = "mm"
    angle_unit: Literal["deg", "rad"]
    joints: list[dict]
    base: list[float] | None = None
    tool: list[float] | None = None
    markers: dict[str, list[float]] | None = None
    joint_limits: list[tuple[float, float]] | None = None
    tolerances: Tolerances = Tolerances()
    fixed: list[str] = []
    joint_errors: dict | None = None  # checked by kinecal.io.joint_errors_file

    @field_validator("joints")
    @classmethod
    def _some_joints(cls, v: list[dict]) -> list[dict]:
        if not v:
            raise ValueError("at least one joint is required")
        return v

    @field_validator("base")
    @classmethod
    def _base6(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and len(v) not in (6, 9):
            raise ValueError(f"expected 6 values [x, y, z, rx, ry, rz] (or 9 with the local "
                             f"rotation error wx, wy, wz), got {len(v)}")
        return v

    @field_validator("tool")
    @classmethod
    def _tool36(cls, v: list[float] | None) -> list[float] | None:
        if v is not None and len(v) not in (3, 6, 9):
            raise ValueError(f"expected 3 values [x, y, z] or 6 with rx, ry, rz (or 9 with "
                             f"the local rotation error wx, wy, wz), got {len(v)}")
        return v

    @field_validator("markers")
    @classmethod
    def _markers3(cls, v: dict[str, list[float]] | None) -> dict[str, list[float]] | None:
        if v is not None:
            if not v:
                raise ValueError("expected at least one marker NAME: [x, y, z]")
            bad = [k for k, p in v.items() if len(p) != 3]
            if bad:
                raise ValueError(f"marker {bad[0]}: expected 3 values [x, y, z]")
        return v


def entry_spec(convention: str, entry: dict) -> type[BaseModel]:
    """The schema of one chain entry: a fixed frame (``frame`` key) or a joint."""
    urdf = convention == "urdf"
    if "frame" in entry:
        return URDFFrameSpec if urdf else FrameSpec
    return URDFJointSpec if urdf else JointSpec
