"""kinecal: kinematic calibration of serial robots, hand-eye setups and parallel-link CMMs.

The top-level names are imported lazily so that ``import kinecal`` stays fast and the
command line starts quickly.
"""

from __future__ import annotations

from kinecal import _blas  # noqa: F401  (records the BLAS environment before numpy loads)
from kinecal._lazy import lazy_exports
from kinecal.errors import InputError

__version__ = "0.1.0"

_LAZY = {
    "SerialModel": "kinecal.kinematics.serial.model",
    "load_model": "kinecal.io.models",
    "save_model": "kinecal.io.models",
    "read_measurements": "kinecal.io.measurements",
    "load_result": "kinecal.io.results",
    "read_kind": "kinecal.io.kinds",
    "Measurements": "kinecal.data",
    "GaugeMeasurements": "kinecal.data",
    "simulate": "kinecal.calibration.serial.simulate",
    "calibrate": "kinecal.calibration.serial.api",
    "calibrate_error_model": "kinecal.calibration.serial.error_model",
    "JointErrors": "kinecal.kinematics.serial.joint_errors",
    "CalibrationResult": "kinecal.calibration.serial.result",
    "StewartPlatform": "kinecal.kinematics.stewart.platform",
    "load_geometry": "kinecal.io.geometry",
    "calibrate_handeye": "kinecal.calibration.handeye",
    "calibrate_handeye_images": "kinecal.vision.pipeline",
    "calibrate_arm_images": "kinecal.vision.arm_images",
    "compensate": "kinecal.compensation.api",
}

__all__ = ["InputError", "__version__", *_LAZY]

__getattr__, _dir = lazy_exports(__name__, _LAZY)


def __dir__() -> list[str]:
    return sorted(__all__)
