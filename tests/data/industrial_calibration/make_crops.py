"""How the files beside this script were made from industrial_calibration's example data.

Run once by hand (not by the tests), with a checkout of ros-industrial/industrial_calibration
at commit fe62b7c9b7b347ee047a6fee6f417cd8427b2836:

    python make_crops.py CHECKOUT/examples/data OUT_DIR

Each image is read as 8-bit grey, cropped to the board (the detected markers or dots grown
by 25 % about their centre) and written as PNG; ``crops.csv`` records where each crop sat in
the full image, so the tests paste it back into a frame of the original size (the rest a
flat grey) and the original intrinsics still apply. The robot poses (metres, quaternions in
one YAML file per image) become one kinecal CSV in millimetres.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import yaml

from kinecal.vision.boards import parse_board
from kinecal.vision.detect import detect

CHARUCO = ("test_set_charuco", "charuco:5x7:36.195:18.256:DICT_6X6_250", (2, 4, 15))
CIRCLES = ("test_set_10x10", "modcircles:10x10:25.4", tuple(range(15)))


def board_points(gray: np.ndarray, spec: str) -> np.ndarray:
    """Pixels of the board's markers (ChArUco) or dots (circle grid)."""
    board = parse_board(spec)
    if board.kind == "charuco":
        params = cv2.aruco.CharucoParameters()
        params.tryRefineMarkers = True
        det = cv2.aruco.CharucoDetector(board.cv_board(), params,
                                        cv2.aruco.DetectorParameters())
        markers = det.detectBoard(gray)[2]
        return np.concatenate([m.reshape(-1, 2) for m in markers])
    found = detect(gray, board)
    assert found.ok, found.reason
    return found.corners


def crop_set(src: Path, dst: Path, name: str, spec: str, ids: tuple[int, ...]) -> None:
    (dst / name / "images").mkdir(parents=True, exist_ok=True)
    rows = ["image,x0,y0,width,height,full_width,full_height"]
    for i in ids:
        gray = cv2.imread(str(src / name / "images" / f"{i}.png"), cv2.IMREAD_GRAYSCALE)
        pts = board_points(gray, spec)
        c = pts.mean(axis=0)
        lo = np.maximum(np.floor(c + (pts.min(axis=0) - c) * 1.25).astype(int), 0)
        hi = np.minimum(np.ceil(c + (pts.max(axis=0) - c) * 1.25).astype(int),
                        [gray.shape[1], gray.shape[0]])
        crop = gray[lo[1]:hi[1], lo[0]:hi[0]]
        cv2.imwrite(str(dst / name / "images" / f"{i}.png"), crop,
                    [cv2.IMWRITE_PNG_COMPRESSION, 9])
        rows.append(f"{i}.png,{lo[0]},{lo[1]},{crop.shape[1]},{crop.shape[0]},"
                    f"{gray.shape[1]},{gray.shape[0]}")
    (dst / name / "crops.csv").write_text("\n".join(rows) + "\n")


def robot_poses(src: Path, dst: Path, name: str, ids: tuple[int, ...]) -> None:
    lines = ["image,flange_x,flange_y,flange_z,flange_qw,flange_qx,flange_qy,flange_qz"]
    for i in ids:
        p = yaml.safe_load((src / name / "poses" / f"{i}.yaml").read_text())
        values = (p["x"] * 1000, p["y"] * 1000, p["z"] * 1000, p["qw"], p["qx"], p["qy"],
                  p["qz"])
        lines.append(f"{i}.png," + ",".join(repr(float(v)) for v in values))
    (dst / name / "robot_poses.csv").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    source, target = Path(sys.argv[1]), Path(sys.argv[2])
    for set_name, board_spec, numbers in (CHARUCO, CIRCLES):
        crop_set(source, target, set_name, board_spec, numbers)
    robot_poses(source, target, CIRCLES[0], CIRCLES[2])
