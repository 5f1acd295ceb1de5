"""The models and measurements the Python entry points take: objects, or paths and bundled
names loaded for the caller (``kinecal.calibrate("ur5", "meas.csv")``); anything else is a
`TypeError` naming what is expected, never an ``AttributeError`` from deep inside.

The readers are late imports (`kinecal.io`): this module sits below the file layer.
"""

from __future__ import annotations

from os import PathLike
from typing import Any

from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["as_calibrated", "as_measurements", "as_model", "is_path", "is_system"]


def is_system(model: Any) -> bool:
    """True for a robot system (`kinecal.kinematics.tree.SystemModel`: several chains),
    which every calibration takes down the stacked problem of `kinecal.calibration.blocks`."""
    return getattr(model, "convention", None) == "system"


def is_path(obj: Any) -> bool:
    """A file path or a bundled name (str, bytes or `os.PathLike`)."""
    return isinstance(obj, str | bytes | PathLike)


def _path(obj: Any) -> str:
    return obj.decode() if isinstance(obj, bytes) else str(obj)


def as_model(model: Any, what: str = "model") -> SerialModel:
    """`model` itself, or the model a bundled name or a model file / URDF path names (a
    system file gives a system)."""
    if isinstance(model, SerialModel) or is_system(model):
        return model
    if is_path(model):
        from kinecal.io.systems import load_machine

        return load_machine(_path(model))
    raise TypeError(f"{what}: expected a SerialModel, a bundled model name or a model file "
                    f"path (kinecal.load_model), got {type(model).__name__}")


def as_measurements(data: Any, model: SerialModel, what: str = "data") -> Any:
    """`data` itself (`Measurements`, a measurement set of another kind, or a list of
    sets), or what a CSV path or a bundled ``NAME:PART`` holds, read for `model` (its kind
    from its columns, `kinecal.io.kinds.read_kind`; paths in a list too)."""
    if data is None or isinstance(data, Measurements) or hasattr(data, "kind"):
        return data
    if is_path(data):
        return _read(data, model)
    if isinstance(data, list | tuple):
        return [_read(d, model) if is_path(d) else d for d in data]
    raise TypeError(f"{what}: expected Measurements (kinecal.read_measurements(path, model)), "
                    f"a measurement CSV path or a bundled NAME:PART, got {type(data).__name__}")


def _read(spec: Any, model: SerialModel) -> Any:
    if is_system(model):
        from kinecal.io.system_data import read_system_data

        return read_system_data(_path(spec), model)
    from kinecal.io.kinds import read_kind

    return read_kind(_path(spec), model)


def as_calibrated(calibrated: Any, nominal: Any = None) -> Any:
    """A calibrated arm given as a path: a result JSON (`kinecal.load_result`, with
    `nominal` the model it calibrated when the result names none that is bundled) or a
    calibrated model file; anything else is returned as it is."""
    if not is_path(calibrated):
        return calibrated
    path = _path(calibrated)
    if path.lower().endswith(".json"):
        from kinecal.io.results import load_result

        return load_result(path, nominal)
    return as_model(path, "calibrated")
