"""Real images of industrial_calibration's example sets (tests/data/industrial_calibration,
Apache-2.0, cropped to the board): its ChArUco board where OpenCV's default detection finds
too few corners, and its modified circle grid from a hand-eye recording."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from kinecal.io.handeye import read_robot_poses
from kinecal.spatial import rot_z, rotation_angle
from kinecal.vision.boards import parse_board
from kinecal.vision.detect import detect
from kinecal.vision.intrinsics import read_intrinsics
from kinecal.vision.pipeline import calibrate_handeye_images
from kinecal.vision.pnp import board_pose

cv2 = pytest.importorskip("cv2")

DATA = Path(__file__).resolve().parents[1] / "data" / "industrial_calibration"


def frames(name: str) -> dict[str, np.ndarray]:
    """The cropped images pasted back into flat grey frames of the original size."""
    out = {}
    with open(DATA / name / "crops.csv", newline="") as f:
        for row in csv.DictReader(f):
            crop = cv2.imread(str(DATA / name / "images" / row["image"]), cv2.IMREAD_GRAYSCALE)
            full = np.full((int(row["full_height"]), int(row["full_width"])), 128, np.uint8)
            x0, y0 = int(row["x0"]), int(row["y0"])
            full[y0:y0 + crop.shape[0], x0:x0 + crop.shape[1]] = crop
            out[row["image"]] = full
    return out


def test_charuco_markers_opencv_misses_are_found_from_the_layout():
    """Images 2, 4 and 15 of test_set_charuco: OpenCV's default ChArUco detection
    interpolates 4, 14 and 8 of 24 corners (all rejected by the 60 % default); the
    board-guided second marker search finds all 17 markers and 24 corners, at OpenCV's own
    corner positions (kinecal re-refines them: median 0.05 px apart over the 16 images),
    fitting one board pose to a fraction of a pixel."""
    board = parse_board("charuco:5x7:36.195:18.256:DICT_6X6_250")
    intr = read_intrinsics(DATA / "test_set_charuco" / "camera.yaml")
    plain = cv2.aruco.CharucoDetector(board.cv_board())
    params = cv2.aruco.CharucoParameters()
    params.tryRefineMarkers = True
    guided = cv2.aruco.CharucoDetector(board.cv_board(), params, cv2.aruco.DetectorParameters())
    diffs = []
    for name, img in frames("test_set_charuco").items():
        ids = plain.detectBoard(img)[1]
        assert ids is None or len(ids) < 15, name  # what kinecal used to reject
        det = detect(img, board)
        assert det.ok and len(det.corners) == 24, (name, det.reason)
        assert det.seen == "17 of 17 markers found, 24 of 24 corners interpolated"
        corners, ids, _, _ = guided.detectBoard(img)
        theirs = dict(zip(ids.ravel().tolist(), corners.reshape(-1, 2), strict=True))
        diffs += [np.linalg.norm(c - theirs[int(i)]) for c, i in zip(det.corners, det.ids,
                                                                      strict=True)]
        pose = board_pose(det.object_points(board), det.corners, intr.K, intr.dist)
        assert pose.rms_px < 1.0, (name, pose.rms_px)
    diffs = np.array(diffs)
    assert np.median(diffs) < 0.1 and diffs.max() < 1.0


def test_modified_circle_grid_hand_eye_recording():
    """test_set_10x10 (eye-in-hand, nominal Kinect intrinsics): every image's grid is found
    with its origin dot where industrial_calibration puts it, every station agrees with the
    robot poses (no outlier; a turned grid would be one), and X turns the camera by -90 deg
    about the flange z as industrial_calibration's camera_mount_to_camera_guess says."""
    board = parse_board("modcircles:10x10:25.4")
    images = frames("test_set_10x10")
    names, F = read_robot_poses(DATA / "test_set_10x10" / "robot_poses.csv")
    intr = read_intrinsics(DATA / "test_set_10x10" / "camera.yaml")
    res = calibrate_handeye_images([images[n] for n in names], F, board, names=names,
                                   intrinsics=intr)
    for r in res.records:
        # the origin dot (id 90, twice the others' size) is the grid's bottom-left corner in
        # these views: below id 0 and left of id 99
        c = r.detection.corners.reshape(10, 10, 2)
        assert c[9, 0, 1] > c[0, 0, 1] + 100 and c[9, 0, 0] < c[9, 9, 0] - 100, r.name
    assert len(res.used) == 15 and res.outliers == []
    assert res.refinement.rms_px < 3.0  # nominal intrinsics: 2.3 px
    guess = rot_z(-np.pi / 2)
    assert np.degrees(rotation_angle(guess.T @ res.X[:3, :3])) < 3.0
