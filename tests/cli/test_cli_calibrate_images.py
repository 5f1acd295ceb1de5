"""``kinecal simulate --images`` and ``kinecal calibrate --images``: rendered stations of a
perturbed arm calibrated end to end (small images, few stations), and the user's mistakes
(exit 2 and nothing written, or a named warning)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from kinecal.calibration.camera.evaluate import aligned_tool_errors
from kinecal.calibration.serial.simulate import read_truth
from kinecal.cli import main
from kinecal.io.models import load_model
from kinecal.vision.intrinsics import CameraIntrinsics, write_intrinsics

K = np.array([[600.0, 0.0, 239.5], [0.0, 600.0, 179.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.1, 0.03, 0.0005, -0.0003, 0.0])
BOARD = "chessboard:9x6:25"


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("arm")
    write_intrinsics(d / "cam.yaml", CameraIntrinsics(K, DIST, (480, 360)))
    code = main(["simulate", "kr6-craig", "--images", str(d / "images"), "--board", BOARD,
                 "--poses", "10", "--home", "0,15,15,0,60,0", "--seed", "11", "--noise", "2",
                 "--blur", "0.7", "--intrinsics", str(d / "cam.yaml"),
                 "--out", str(d / "stations.csv"), "--truth-out", str(d / "truth.json"),
                 "--quiet"])
    assert code == 0
    return d


def _copy(scene, tmp_path):
    shutil.copytree(scene, tmp_path / "s")
    return tmp_path / "s"


def test_simulated_stations_calibrate_the_arm(scene, tmp_path, capsys):
    out, cal, rep = tmp_path / "r.json", tmp_path / "cal.yaml", tmp_path / "r.html"
    code = main(["calibrate", "kr6-craig", str(scene / "stations.csv"), "--images",
                 str(scene / "images"), "--board", BOARD, "--intrinsics",
                 str(scene / "cam.yaml"), "--out", str(out), "--model-out", str(cal),
                 "--report", str(rep)])
    text = capsys.readouterr()
    assert code == 0, text.err
    assert "base frame against the board pose" in text.out
    res = json.loads(out.read_text())
    assert res["kind"] == "camera" and len(res["free"]) == 17 and not res["warnings"]
    assert res["calibration"]["after"]["rms_px"] < 0.1 * res["calibration"]["before"]["rms_px"]
    for name in ("alpha1", "theta1", "d1", "theta6", "d6", "tool.x"):
        assert name in res["held"]
    nominal = load_model("kr6-craig")
    calibrated = load_model(str(cal))
    assert "held at nominal, not seen by a camera: alpha1, a1, theta1, d1" in \
        calibrated.description
    truth = read_truth(scene / "truth.json", nominal)
    q = np.radians(np.random.default_rng(0).uniform(-40, 40, (50, 6))) + np.radians(
        [0, 15, 15, 0, 60, 0])
    before = aligned_tool_errors(nominal, nominal.nominal, truth, q)
    after = aligned_tool_errors(nominal, calibrated.nominal, truth, q)
    assert np.sqrt(np.mean(after**2)) < 0.25 * np.sqrt(np.mean(before**2))  # 14 % here
    assert "What the camera cannot identify" in rep.read_text()


def test_same_seed_same_stations(scene, tmp_path):
    code = main(["simulate", "kr6-craig", "--images", str(tmp_path / "im"), "--board", BOARD,
                 "--poses", "10", "--home", "0,15,15,0,60,0", "--seed", "11", "--noise", "2",
                 "--blur", "0.7", "--intrinsics", str(scene / "cam.yaml"),
                 "--out", str(tmp_path / "st.csv"), "--quiet"])
    assert code == 0
    assert (tmp_path / "st.csv").read_bytes() == (scene / "stations.csv").read_bytes()
    a = (tmp_path / "im" / "station_004.png").read_bytes()
    assert a == (scene / "images" / "station_004.png").read_bytes()


def _calibrate(folder, *extra, board=BOARD):
    return main(["calibrate", "kr6-craig", str(folder / "stations.csv"), "--images",
                 str(folder / "images"), "--board", board, "--intrinsics",
                 str(folder / "cam.yaml"), "--out", str(folder / "r.json"), *extra])


def test_images_without_joints_exit_2(scene, tmp_path, capsys):
    s = _copy(scene, tmp_path)
    shutil.copy(s / "images" / "station_000.png", s / "images" / "extra.png")
    assert _calibrate(s) == 2
    assert "without joints" in capsys.readouterr().err and not (s / "r.json").exists()


def test_joints_without_images_exit_2(scene, tmp_path, capsys):
    s = _copy(scene, tmp_path)
    (s / "images" / "station_003.png").unlink()
    assert _calibrate(s) == 2
    err = capsys.readouterr().err
    assert "station_003.png" in err and "row 4" in err and not (s / "r.json").exists()


def test_a_station_without_board_is_skipped_with_its_reason(scene, tmp_path, capsys):
    import cv2

    s = _copy(scene, tmp_path)
    cv2.imwrite(str(s / "images" / "station_002.png"), np.full((360, 480), 128, np.uint8))
    assert _calibrate(s) == 0
    assert "[station-skipped]" in capsys.readouterr().err
    res = json.loads((s / "r.json").read_text())
    assert [r["image"] for r in res["skipped"]] == ["station_002.png"]
    assert res["skipped"][0]["reason"].startswith("no board found")
    assert res["n_used"] == 9 and [w["code"] for w in res["warnings"]] == ["station-skipped"]


def test_a_board_spec_matching_no_image_exit_2(scene, tmp_path, capsys):
    s = _copy(scene, tmp_path)
    lines = (s / "stations.csv").read_text().splitlines()
    (s / "stations.csv").write_text("\n".join(lines[:4]) + "\n")  # 3 stations: quicker
    for k in range(3, 10):
        (s / "images" / f"station_{k:03d}.png").unlink()
    assert _calibrate(s, board="chessboard:7x5:25") == 2
    err = capsys.readouterr().err
    assert "0 usable station(s) of 3" in err and "board size differs" in err
    assert not (s / "r.json").exists()


def test_a_chain_that_ends_before_the_camera_exit_2(scene, tmp_path, capsys):
    s = _copy(scene, tmp_path)
    lines = (s / "stations.csv").read_text().splitlines()
    (s / "stations.csv").write_text("\n".join([lines[0] + ",q7"]
                                              + [ln + ",0" for ln in lines[1:]]) + "\n")
    assert _calibrate(s) == 2
    err = capsys.readouterr().err
    assert "q7 beyond model 'kr6-craig'" in err and "chain ends before" in err


def test_joints_that_do_not_fit_the_images_are_named(scene, tmp_path, capsys):
    """Eye-in-hand stations given as eye-to-hand, or joints of another order: no camera mount
    fits them; exit 2 saying which."""
    s = _copy(scene, tmp_path)
    assert _calibrate(s, "--setup", "eye-to-hand") == 2
    assert "they fit --setup eye-in-hand" in capsys.readouterr().err
    lines = (s / "stations.csv").read_text().splitlines()
    swapped = [",".join(c[:2] + [c[3], c[2]] + c[4:]) for c in (ln.split(",")
                                                                for ln in lines[1:])]
    (s / "stations.csv").write_text("\n".join([lines[0], *swapped]) + "\n")  # q2, q3 swapped
    assert _calibrate(s) == 2
    assert "fit no camera mount of model 'kr6-craig'" in capsys.readouterr().err
    assert not (s / "r.json").exists()


def test_position_options_are_refused_with_images(scene, tmp_path, capsys):
    s = _copy(scene, tmp_path)
    assert _calibrate(s, "--sigma", "0.1") == 2
    assert "--sigma" in capsys.readouterr().err and not (s / "r.json").exists()


def test_validation_stations_are_reprojected_not_fitted(scene, tmp_path):
    s = _copy(scene, tmp_path)
    lines = (s / "stations.csv").read_text().splitlines()
    (s / "stations.csv").write_text("\n".join(lines[:9]) + "\n")
    (s / "val.csv").write_text("\n".join([lines[0], *lines[9:]]) + "\n")
    assert _calibrate(s, "--validate", str(s / "val.csv")) == 0
    res = json.loads((s / "r.json").read_text())
    assert res["calibration"]["after"]["n"] == 8 and res["validation"]["after"]["n"] == 2
    assert res["validation"]["images"] == ["station_008.png", "station_009.png"]
    assert res["validation"]["after"]["rms_px"] < 0.5 * res["validation"]["before"]["rms_px"]


def test_min_corners_reaches_the_detection_and_is_checked(scene, tmp_path, capsys,
                                                          monkeypatch):
    """``--min-corners`` (ChArUco boards seen in part) as for handeye-images: checked against
    the board, handed to the detection, refused without --images, and refused for a board
    found whole or not at all (a chessboard: it used to be accepted and do nothing)."""
    import kinecal.vision.arm_images as arm

    seen = {}

    def spy(*args, **kwargs):  # the limits the detection would get; no need to detect
        seen["limits"] = kwargs["limits"]
        raise arm.InputError("stop")

    monkeypatch.setattr(arm, "calibrate_arm_images", spy)
    s = _copy(scene, tmp_path)
    charuco = "charuco:10x7:25:18:DICT_6X6_250"
    assert _calibrate(s, "--min-corners", "40", board=charuco) == 2
    assert seen["limits"].min_corners == 40 and "stop" in capsys.readouterr().err
    for bad in ("3", "1000"):
        assert _calibrate(s, "--min-corners", bad, board=charuco) == 2
        assert "option --min-corners" in capsys.readouterr().err
    assert _calibrate(s, "--min-corners", "40") == 2
    err = capsys.readouterr().err
    assert "option --min-corners" in err and "chessboard:9x6:25 is found whole" in err
    assert not (s / "r.json").exists()
    assert main(["calibrate", "kr6-craig", str(s / "stations.csv"), "--min-corners", "10"]) == 2
    assert "applies to --images only" in capsys.readouterr().err
