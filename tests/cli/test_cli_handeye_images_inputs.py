"""``kinecal handeye-images`` on a user's mistakes: one image of another size (first or
not) is the one rejected, and a board spec with the wrong inner-corner counts is named as
such, not as a board "partly visible"."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from kinecal.cli import main
from kinecal.vision.boards import parse_board
from kinecal.vision.render import ImageConditions, render_handeye_scene, write_scene

K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.04, 0.0005, -0.0003, 0.0])


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    sc = render_handeye_scene(parse_board("chessboard:9x6:20"), K, DIST, (480, 360), 6,
                              conditions=ImageConditions(blur=0.7, noise=2.0), seed=5,
                              supersample=2)
    return write_scene(sc, tmp_path_factory.mktemp("scene"))


def test_an_odd_sized_first_image_is_the_one_rejected(folder, capsys):
    img = folder / "images" / "station_000.png"
    original = img.read_bytes()
    try:
        cv2.imwrite(str(img), cv2.resize(cv2.imread(str(img)), (240, 180)))
        code = main(["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
                     "--board", "chessboard:9x6:20", "--intrinsics",
                     str(folder / "camera.yaml"), "--json"])
    finally:
        img.write_bytes(original)
    out = capsys.readouterr().out
    assert code == 0  # before: exit 2, the 5 good images rejected against the first one
    res = json.loads(out)
    assert res["n_used"] == 5
    assert [r["image"] for r in res["rejected"]] == ["station_000.png"]
    assert "240x180 differs from the other images' 480x360" in res["rejected"][0]["reason"]


@pytest.mark.parametrize("spec", ["chessboard:10x7:20", "chessboard:8x5:20"])
def test_wrong_inner_corner_counts_are_named(folder, spec, capsys):
    code = main(["handeye-images", str(folder / "images"), str(folder / "robot_poses.csv"),
                 "--board", spec, "--intrinsics", str(folder / "camera.yaml")])
    err = capsys.readouterr().err
    assert code == 2
    assert "board size differs" in err, err  # before: "board partly visible: 6"
    assert "chessboard of 9x6 inner corners" in err or "of 6x9 inner corners" in err, err
