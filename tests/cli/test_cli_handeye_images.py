"""``kinecal handeye-images``: the CLI contract, rejections with reasons, exit codes."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from kinecal.calibration.handeye.errors import pose_error
from kinecal.cli import main
from kinecal.vision.boards import parse_board
from kinecal.vision.render import (
    ImageConditions,
    render_board,
    render_handeye_scene,
    write_scene,
)

K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.04, 0.0005, -0.0003, 0.0])
SPEC = "chessboard:9x6:20"


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    """7 good stations plus a board-less, a half-board and a blurred image (each with a
    robot pose row), written like a user's recording."""
    board = parse_board(SPEC)
    sc = render_handeye_scene(board, K, DIST, (480, 360), 7,
                              conditions=ImageConditions(blur=0.7, noise=2.0), seed=3,
                              supersample=2)
    folder = write_scene(sc, tmp_path_factory.mktemp("scene"))
    T = sc.target2cam[0]
    away, half = T.copy(), T.copy()
    away[0, 3] += 3.0 * T[2, 3]
    half[0, 3] += T[2, 3] * 0.45 * 480 / K[0, 0]
    bad = {"empty.png": render_board(board, K, DIST, away, (480, 360)),
           "half.png": render_board(board, K, DIST, half, (480, 360)),
           "blurred.png": render_board(board, K, DIST, T, (480, 360),
                                       ImageConditions(blur=5.0, noise=2.0), rng=0)}
    lines = (folder / "robot_poses.csv").read_text().splitlines()
    for name, img in bad.items():
        cv2.imwrite(str(folder / "images" / name), img)
        lines.append(name + "," + lines[1].split(",", 1)[1])
    (folder / "robot_poses.csv").write_text("\n".join(lines) + "\n")
    return folder, sc


def test_json_contract_and_rejections(scene_dir, capsys, tmp_path):
    folder, sc = scene_dir
    report = tmp_path / "r.html"
    code = main(["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
                 "--board", SPEC, "--intrinsics", str(folder / "camera.yaml"), "--json",
                 "--report", str(report)])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    X = np.array(out["X"])
    assert X.shape == (4, 4) and out["X_frame"] == "cam2flange"
    rot, tr = pose_error(X, sc.X)
    assert rot < 0.02 and tr < 0.1
    assert pose_error(np.array(out["target"]), sc.target)[1] < 0.2
    assert out["board_pose"] == out["target"] and out["target_frame"] == "target2base"
    assert len(out["X_std"]["rotation_deg"]) == 3 and len(out["X_std"]["translation"]) == 3
    assert out["n_images"] == 10 and out["n_used"] == 7
    rejected = {r["image"]: r["reason"] for r in out["rejected"]}
    assert rejected["empty.png"].startswith("no board found")
    assert rejected["half.png"].startswith("board partly visible")
    assert "blurred" in rejected["blurred.png"]
    per_image = {r["image"]: r for r in out["images"]}
    assert per_image["station_000.png"]["status"] == "used"
    assert 0 < per_image["station_000.png"]["rms_px"] < 0.5
    assert per_image["half.png"]["rms_px"] is None
    assert out["intrinsics"]["source"] == "camera.yaml" and out["warnings"] == []
    html = report.read_text()
    assert "Detections" in html and html.count("data:image/jpeg") == 10
    assert "board partly visible" in html and "cam2flange" in html


def test_intrinsics_estimated_and_text_summary(scene_dir, capsys):
    folder, _ = scene_dir
    code = main(["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
                 "--board", SPEC])
    assert code == 0
    text = capsys.readouterr().out
    assert "X (cam2flange" in text and "X std (1 sigma)" in text and "mm" in text
    assert "estimated from 7 images, refined with X" in text and "rejected: blurred.png" in text


def test_exit_2_on_bad_folders_and_files(scene_dir, tmp_path, capsys):
    folder, _ = scene_dir
    csv = folder / "robot_poses.csv"
    empty = tmp_path / "empty"
    empty.mkdir()
    cases = [
        ([str(empty), str(csv), "--board", SPEC], "no images"),
        ([str(tmp_path / "nope"), str(csv), "--board", SPEC], "not found"),
        ([str(folder / "images"), str(csv), "--board", "chessboard:9x6"], "--board"),
        ([str(folder / "images"), str(csv), "--board", SPEC, "--setup", "eye-on-hand"],
         "setup"),
        ([str(folder / "images"), str(csv), "--board", SPEC, "--out", str(csv)],
         "overwrite"),
    ]
    extra = tmp_path / "extra"
    shutil.copytree(folder / "images", extra)
    cv2.imwrite(str(extra / "zz_more.png"), np.zeros((360, 480), np.uint8))
    cases.append(([str(extra), str(csv), "--board", SPEC], "11 images"))
    short = tmp_path / "short.csv"
    short.write_text("\n".join(csv.read_text().splitlines()[:-1]) + "\n")
    cases.append(([str(folder / "images"), str(short), "--board", SPEC], "robot poses"))
    renamed = tmp_path / "renamed.csv"
    renamed.write_text(csv.read_text().replace("station_002.png", "station_999.png"))
    cases.append(([str(folder / "images"), str(renamed), "--board", SPEC], "row 3"))
    nocol = tmp_path / "nocol.csv"
    nocol.write_text(csv.read_text().replace("flange_qw", "qw"))
    cases.append(([str(folder / "images"), str(nocol), "--board", SPEC], "flange_qw"))
    badq = tmp_path / "badq.csv"
    rows = csv.read_text().splitlines()
    cells = rows[2].split(",")
    cells[4] = "3.0"
    badq.write_text("\n".join([rows[0], rows[1], ",".join(cells), *rows[3:]]) + "\n")
    cases.append(([str(folder / "images"), str(badq), "--board", SPEC], "row 2"))
    for args, match in cases:
        assert main(["handeye-images", *args]) == 2, args
        err = capsys.readouterr().err
        assert err.startswith("kinecal: error:") and match in err, (match, err)
        assert len(err.strip().splitlines()) == 1


def test_too_few_usable_images_is_exit_2(tmp_path, capsys):
    board = parse_board(SPEC)
    img = render_board(board, K, DIST, np.eye(4) @ np.diag([1, 1, 1, 1.0]), (480, 360))
    (tmp_path / "im").mkdir()
    lines = ["image,flange_x,flange_y,flange_z,flange_qw,flange_qx,flange_qy,flange_qz"]
    for i in range(4):
        cv2.imwrite(str(tmp_path / "im" / f"{i}.png"), img)
        lines.append(f"{i}.png,0,0,{i},1,0,0,0")
    (tmp_path / "p.csv").write_text("\n".join(lines) + "\n")
    assert main(["handeye-images", str(tmp_path / "im"), str(tmp_path / "p.csv"), "--board",
                 SPEC]) == 2
    err = capsys.readouterr().err
    assert "0 usable image(s) of 4" in err and "no board found: 4" in err


def test_robot_noise_option(scene_dir, capsys):
    folder, _ = scene_dir
    args = ["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
            "--board", SPEC, "--intrinsics", str(folder / "camera.yaml")]
    assert main([*args, "--json", "--robot-noise", "0.01,0.05", "--fix-intrinsics"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["robot_corrections"]) == 7 and not out["intrinsics"]["refined"]
    for bad in ("0.01", "-1,2", "a,b"):
        assert main([*args, "--robot-noise", bad]) == 2
        assert "--robot-noise" in capsys.readouterr().err
