"""``kinecal handeye`` / ``handeye-images`` on a SCARA (rotations about one axis only):
--camera-height and --board-contact, the warning without them; ``--min-corners``."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from kinecal.calibration.handeye.camera import project
from kinecal.calibration.handeye.errors import pose_error
from kinecal.cli import main
from kinecal.io.handeye import pose_columns
from kinecal.spatial import (
    invert_transform,
    matrix_from_rpy,
    pq_from_transform,
    rot_z,
    transform_from,
)
from kinecal.vision.boards import parse_board
from kinecal.vision.render import ImageConditions, render_handeye_scene, write_scene

K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.04, 0.0005, -0.0003, 0.0])
DOWN = matrix_from_rpy([np.pi, 0.0, 0.0])
X = transform_from(matrix_from_rpy([0.03, -0.02, 0.7]), [60.0, -25.0, -40.0])  # cam2flange
CAMERA_HEIGHT = 40.0  # the camera sits 40 mm above the flange along the base's +z


def scara_views(board, target, n, seed):
    """Flange poses of a SCARA (tool flange facing down, any yaw) whose camera looks down
    at the board from 420-470 mm."""
    rng = np.random.default_rng(seed)
    centre = (target @ np.r_[board.object_points.mean(axis=0), 1.0])[:3]
    F = []
    for _ in range(n):
        R = rot_z(rng.uniform(-1.2, 1.2)) @ DOWN
        cam = centre + [rng.uniform(-20, 20), rng.uniform(-15, 15), rng.uniform(420, 470)]
        F.append(transform_from(R, cam - R @ X[:3, 3]))
    return np.array(F)


@pytest.fixture(scope="module")
def scara_scene(tmp_path_factory):
    """8 stations of an eye-in-hand SCARA over industrial_calibration's modified circle
    grid lying on the table (printed side up: its z points up)."""
    board = parse_board("modcircles:7x5:15")
    target = transform_from(rot_z(0.4), [450.0, 20.0, 0.0])
    F = scara_views(board, target, 8, seed=0)
    sc = render_handeye_scene(board, K, DIST, (480, 360), 8, X=X, target=target,
                              flange2base=F, conditions=ImageConditions(noise=2.0, blur=0.6),
                              seed=1, supersample=2)
    return write_scene(sc, tmp_path_factory.mktemp("scara")), sc


def test_handeye_images_scara_with_camera_height(scara_scene, capsys):
    folder, sc = scara_scene
    args = ["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
            "--board", "modcircles:7x5:15", "--intrinsics", str(folder / "camera.yaml")]
    assert main([*args, "--camera-height", str(CAMERA_HEIGHT), "--json"]) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert out["method"] == "ulrich-steger" and out["warnings"] == [] and cap.err == ""
    r, t = pose_error(np.array(out["X"]), sc.X)
    assert r < 0.01 and t < 0.05, (r, t)  # measured 0.0018 deg, 0.013 mm
    one = out["one_axis"]
    assert one["height_from"] == "camera-height" and one["camera_height"] == pytest.approx(40.0)
    assert np.allclose(one["axis_base"], [0, 0, 1], atol=1e-9)
    # without the height: solved, the height assumed, named
    assert main(args) == 0
    cap = capsys.readouterr()
    assert "[handeye-one-axis]" in cap.err and "ASSUMED 0" in cap.out
    assert main([*args, "--strict"]) == 2


def _pairs_csv(path, F, C):
    cols = pose_columns("flange") + pose_columns("target")
    rows = np.hstack([pq_from_transform(F), pq_from_transform(C)])
    path.write_text(",".join(cols) + "\n" + "\n".join(",".join(repr(float(v)) for v in row)
                                                      for row in rows) + "\n")
    return path


def test_handeye_pairs_scara_board_contact_and_bad_options(scara_scene, tmp_path, capsys):
    _, sc = scara_scene
    F = sc.flange2base_true
    C = invert_transform(X) @ invert_transform(F) @ sc.target
    pairs = str(_pairs_csv(tmp_path / "pairs.csv", F, C))
    touch = (sc.target @ [15.0, 30.0, 0.0, 1.0])[:3]  # the tool tip on the board
    contact = ",".join(f"{v:.12g}" for v in touch)
    assert main(["handeye", pairs, "--board-contact", contact, "--unit", "mm"]) == 0
    text = capsys.readouterr().out
    assert "method ulrich-steger" in text and "from --board-contact" in text
    assert main(["handeye", pairs, "--board-contact", contact, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    r, t = pose_error(np.array(out["X"]), X)
    assert r < 1e-6 and t < 1e-5
    assert out["one_axis"]["camera_height"] == pytest.approx(CAMERA_HEIGHT, abs=1e-6)
    for bad, word in ((["--board-contact", "1,2"], "X,Y,Z"),
                      (["--board-contact", contact, "--camera-height", "3"], "not both")):
        assert main(["handeye", pairs, *bad]) == 2
        err = capsys.readouterr().err
        assert word in err and len(err.strip().splitlines()) == 1


def test_min_corners(tmp_path, capsys):
    """A ChArUco view with a part of the board painted over: rejected below the threshold
    with what was seen, used once --min-corners allows it; out-of-range values exit 2."""
    spec = "charuco:7x5:30:22:DICT_5X5_100"
    board = parse_board(spec)
    sc = render_handeye_scene(board, K, DIST, (480, 360), 5, seed=2, supersample=2,
                              conditions=ImageConditions(noise=1.0))
    folder = write_scene(sc, tmp_path / "charuco")
    img = cv2.imread(str(folder / "images" / sc.names[0]), cv2.IMREAD_GRAYSCALE)
    T = sc.target2cam[0]  # paint over the board left of its middle in the first image
    uv = project(K, DIST, board.object_points @ T[:3, :3].T + T[:3, 3])
    img[:, : int(np.median(uv[:, 0]))] = 235
    cv2.imwrite(str(folder / "images" / sc.names[0]), img)
    args = ["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
            "--board", spec, "--intrinsics", str(folder / "camera.yaml"), "--json"]
    assert main([*args, "--min-corners", "24"]) == 0
    rec = json.loads(capsys.readouterr().out)["images"][0]
    assert rec["status"] == "rejected" and rec["reason"].startswith("too few corners: ")
    n = rec["corners"]
    assert 4 <= n < 24 and f"{n} of 24 corners interpolated; --min-corners 24" in rec["reason"]
    assert rec["seen"] and "markers found" in rec["seen"]
    assert main([*args, "--min-corners", str(n)]) == 0
    assert json.loads(capsys.readouterr().out)["images"][0]["status"] == "used"
    for bad in ("3", "25"):
        assert main([*args, "--min-corners", bad]) == 2
        assert "--min-corners" in capsys.readouterr().err
