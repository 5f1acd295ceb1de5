"""kinecal: kinematic calibration of serial robots, hand-eye setups and parallel-link CMMs.

The top-level names are imported lazily so that ``import kinecal`` stays fast and the
command line starts quickly.
"""

from __future__ import annotations

import importlib
from typing import Any

from kinecal.errors import InputError

__version__ = "0.1.0"

_LAZY = {
    "SerialModel": "kinecal.kinematics.serial",
    "load_model": "kinecal.io.models",
    "save_model": "kinecal.io.models",
    "read_measurements": "kinecal.io.measurements",
    "Measurements": "kinecal.data",
    "simulate": "kinecal.calibration.simulate",
    "calibrate": "kinecal.calibration.serial",
    "calibrate_error_model": "kinecal.calibration.error_model",
    "JointErrors": "kinecal.kinematics.joint_errors",
    "CalibrationResult": "kinecal.calibration.result",
    "StewartPlatform": "kinecal.kinematics.stewart",
    "load_geometry": "kinecal.io.geometry",
    "calibrate_handeye": "kinecal.calibration.handeye",
    "compensate": "kinecal.calibration.compensate",
}

__all__ = ["InputError", "__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'kinecal' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
