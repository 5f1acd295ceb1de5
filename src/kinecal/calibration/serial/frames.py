"""The frames a serial calibration result reports: the base and tool frames composed.

The parameters ``base.rx .. base.rz`` (and ``tool.rx .. tool.rz``) are local rotation errors
about the model's nominal orientation (`kinecal.kinematics.serial.frames`); the result
also gives each frame as a whole pose, nominal and calibrated, in the model file's units
(``frames`` of the result JSON; docs/conventions.md). Its presence marks a result written
with local frames (`kinecal.io.result_values` reads older ones).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinecal.kinematics.serial.frames import frame_pose
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["file_pose", "frames_entry", "station_entries", "station_lines"]


def file_pose(model: SerialModel, pose: np.ndarray) -> list[float]:
    """A pose ``(x, y, z, rx, ry, rz)`` (rad) in the model file's angle unit, as a list."""
    s = 180.0 / np.pi if model.angle_unit == "deg" else 1.0
    return [float(v) for v in np.r_[pose[:3], np.asarray(pose[3:]) * s]]


def frames_entry(model: SerialModel, params: np.ndarray, extra: dict | None = None
                 ) -> dict[str, Any]:
    """``{"base": {"nominal", "calibrated"}, "tool": ..., "stations": ...}``: each frame as
    ``[x, y, z, rx, ry, rz]`` (``R = Rz Ry Rx``; the model file's units); the tool only for
    a tool frame; ``stations`` (several tracker set-ups: the base frame seen from each,
    ``base@NAME``, with its parameters and standard errors) from the stacked result's
    `extra`."""
    out: dict[str, Any] = {}
    if not isinstance(model, SerialModel):  # a system: its chains' frames are its own
        return out
    which = ["base"] + (["tool"] if "tool.rx" in model.parameter_names else [])
    for w in which:
        out[w] = {"nominal": file_pose(model, frame_pose(model, None, w)),
                  "calibrated": file_pose(model, frame_pose(model, params, w))}
    stations = station_entries(model, extra or {})
    if stations:
        out["stations"] = stations
    return out


def station_entries(model: SerialModel, extra: dict) -> dict[str, Any]:
    """``{NAME: {"calibrated": pose, "rows", "parameters", "std"}}`` of every station of the
    stacked result's measurement sets (angles in the model file's unit)."""
    s = 180.0 / np.pi if model.angle_unit == "deg" else 1.0
    out: dict[str, Any] = {}
    for entry in extra.get("kinds", []):
        for u in entry.get("unknowns", []):
            if "station" not in u:
                continue
            def unit(name: str, v: float) -> float:
                return float(v) * (s if name.rsplit(".", 1)[-1].startswith("r") else 1.0)
            out[u["station"]] = {
                "calibrated": file_pose(model, np.asarray(u["pose"])),
                "rows": u["rows"], "file": entry.get("file"),
                "parameters": {n: unit(n, v) for n, v in u["parameters"].items()},
                "std": {n: unit(n, v) for n, v in u["std"].items()}}
    return out


def station_lines(model: SerialModel, extra: dict, unit: str, factor: float) -> list[str]:
    """Text lines of the stations' base frames (summary): lengths times `factor` in `unit`,
    angles in degrees."""
    stations = station_entries(model, extra)
    if not stations:
        return []
    s = 1.0 if model.angle_unit == "deg" else 180.0 / np.pi
    lines = ["", f"stations: the base frame seen from each (x, y, z {unit}; rx, ry, rz deg, "
             "R = Rz Ry Rx)"]
    for name, e in stations.items():
        p = e["calibrated"]
        lines.append(f"  base@{name:10s} {p[0] * factor:12.4f} {p[1] * factor:12.4f} "
                     f"{p[2] * factor:12.4f} {p[3] * s:10.4f} {p[4] * s:10.4f} "
                     f"{p[5] * s:10.4f}   ({e['rows']} rows)")
    return lines
