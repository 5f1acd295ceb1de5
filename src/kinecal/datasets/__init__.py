"""Bundled real measurement data and the example files of the docs, each folder with its
LICENSE.

Addressed as ``NAME:PART`` wherever a CSV path is accepted (``ur5-laser-tracker:grid``);
``kinecal datasets NAME`` writes a set's files into a folder (`files`).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from kinecal.errors import InputError

__all__ = ["DATASETS", "bundled_csv", "dataset_dir", "files"]

#: name -> description, license, the model it belongs to and its parts (file names)
DATASETS: dict[str, dict] = {
    "ur5-laser-tracker": {
        "description": (
            "Universal Robots UR5 measured with a GTS3800 laser tracker (15 um + 6 um/m); "
            "grid: 1000 calibration poses, random: 20 test poses. Measured tool position = "
            "target + dif (see docs/datasets.md)."
        ),
        "source": "P. Jacobi (2025), github.com/pauljac7700/serial_robots_datasets",
        "license": "MIT",
        "model": "ur5",
        "parts": {"grid": "grid.csv", "random": "random.csv"},
    },
    "ur10-ipa": {
        "description": (
            "Universal Robots UR10 carrying a Leica T-Mac measured by a Leica laser tracker "
            "(Landgraf et al., CASE 2021): A, 11911 poses on a grid with temperature and "
            "time; B, 1495 joint configurations in another tracker set-up, with per-axis "
            "standard deviations. T-Mac positions in the tracker frame (mm), joints in deg; "
            "B-tmac with the T-Mac's orientation (--orientation-format intrinsic-xyz:deg); "
            "the model ur10-tmac.yaml and the T-Mac-to-flange transforms (docs/datasets.md)."
        ),
        "source": "C. Landgraf et al. (2021), github.com/christianlandgraf/ipa-robot-accuracy",
        "license": "MIT",
        "model": "ur10",
        "parts": {"A": "A.csv", "B": "B.csv", "B-tmac": "B-tmac.csv", "model": "ur10-tmac.yaml",
                  "A-trafo-init": "A-trafo-init.txt", "A-trafo-calib": "A-trafo-calib.txt",
                  "B-trafo-init": "B-trafo-init.txt", "B-trafo-calib": "B-trafo-calib.txt"},
    },
    "handeye-camodocal": {
        "description": (
            "Real hand-eye recording, 42 stations of (robot base->effector, camera->marker) "
            "4x4 transforms in OpenCV FileStorage YAML; eye-to-hand."
        ),
        "source": "handeye_calib_camodocal (BSD-2-Clause)",
        "license": "BSD-2-Clause",
        "model": None,
        "parts": {"pairs": "TransformPairsInput.yml", "upstream": "CalibratedTransform.yml"},
    },
    "handeye-tabb1": {
        "description": (
            "Real robot-world hand-eye recording (Tabb & Ahmad Yousef 2017, dataset 1): 88 "
            "stations of a camera on a robot gripper viewing a fixed chessboard, mm; eye-in-hand. "
            "pairs: kinecal hand-eye CSV; robot, camera, reference: the upstream files "
            "(reference = the authors' reprojection-error result, X = inverse of its Z)."
        ),
        "source": "Tabb (2017), Ag Data Commons, via OpenCV's test data",
        "license": "U.S. Government work (public domain in the U.S.)",
        "model": None,
        "parts": {"pairs": "pairs.csv", "robot": "robot_cali.txt", "camera": "cali.txt",
                  "reference": "transformations.txt"},
    },
    "kr16-urdf": {
        "description": (
            "KUKA KR 16-2 URDF of ROS-Industrial's kuka_experimental (meshes not included): "
            "the robot of the URDF walkthrough (docs/urdf.md)."
        ),
        "source": "ros-industrial/kuka_experimental kuka_kr16_support, via rtb-data 2.0.0",
        "license": "BSD",
        "model": None,
        "parts": {"urdf": "kr16_2.urdf"},
    },
    "rail-cell": {
        "description": (
            "Synthetic measurements of the bundled rail-cell system (a UR10 on a linear rail "
            "beside a two-axis positioner), made by kinecal simulate from one true cell: "
            "tracker: 40 rows of the rail's carriage and 40 of the arm's probe (0.02 mm "
            "noise); touches: 4 workpiece points on the positioner's table, each touched 8 "
            "times by the probe (0.01 mm); validation: 20 + 20 held-out tracker rows; truth: "
            "the true deviations (docs/systems.md)."
        ),
        "source": "kinecal (synthetic, kinecal simulate; commands in docs/systems.md)",
        "license": "MIT",
        "model": "rail-cell",
        "parts": {"tracker": "tracker.csv", "touches": "touches.csv",
                  "validation": "validation.csv", "truth": "truth.json"},
    },
    "handeye-formats": {
        "description": (
            "One synthetic, noise-free eye-in-hand recording of 9 stations in the formats "
            "robots and cameras write: base2gripper 4x4 rows, KUKA X,Y,Z,A,B,C (deg), board "
            "poses as tvec + rvec (docs/handeye.md)."
        ),
        "source": "kinecal (synthetic)",
        "license": "MIT",
        "model": None,
        "parts": {"base2gripper": "base2gripper.csv", "kuka": "kuka.csv", "board": "board.csv"},
    },
}


def dataset_dir(name: str) -> Path:
    """Folder of a bundled dataset."""
    if name not in DATASETS:
        raise InputError(f"unknown dataset {name!r}; bundled: {', '.join(DATASETS)}")
    return Path(str(resources.files("kinecal") / "datasets" / name))


def files(name: str) -> list[Path]:
    """The files of a bundled set: its parts and its LICENSE."""
    folder = dataset_dir(name)
    return [folder / f for f in DATASETS[name]["parts"].values()] + [folder / "LICENSE"]


def bundled_csv(spec: str) -> Path:
    """Path of ``NAME:PART`` (e.g. ``ur5-laser-tracker:grid``)."""
    name, _, part = spec.partition(":")
    info = DATASETS.get(name)
    if info is None:
        raise InputError(
            f"{spec!r} is neither a file nor a bundled dataset ({', '.join(DATASETS)})"
        )
    if part not in info["parts"]:
        raise InputError(
            f"dataset {name!r} has no part {part!r}; parts: {', '.join(info['parts'])}"
        )
    return dataset_dir(name) / info["parts"][part]
