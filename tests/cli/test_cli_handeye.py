"""``kinecal handeye`` and ``kinecal handeye-poses`` (DESIGN sec. 4 contract)."""

from __future__ import annotations

import json

import numpy as np

from kinecal.cli import main
from kinecal.io.csvtable import read_table
from kinecal.io.handeye import write_handeye_csv, write_handeye_yaml
from kinecal.spatial import (
    invert_transform,
    matrix_from_rpy,
    transform_from,
    transform_from_pq,
)

X_TRUE = transform_from(matrix_from_rpy([0.2, -0.1, 0.9]), [25.0, -15.0, 70.0])
Y_TRUE = transform_from(matrix_from_rpy([0.0, 0.0, 0.5]), [550.0, 80.0, 10.0])


def _write_pairs(tmp_path, kind="csv"):
    from kinecal.calibration.handeye.poses import star_polygon_poses

    cam = star_polygon_poses(380.0, 80.0, 9)
    C = invert_transform(cam)
    F = Y_TRUE @ cam @ invert_transform(X_TRUE)
    path = tmp_path / f"pairs.{kind}"
    (write_handeye_csv if kind == "csv" else write_handeye_yaml)(path, F, C)
    return path


def test_handeye_json_contract(tmp_path, capsys):
    path = _write_pairs(tmp_path)
    out = tmp_path / "res.json"
    assert main(["handeye", str(path), "--method", "tsai", "--json", "--out", str(out)]) == 0
    data = json.loads(capsys.readouterr().out)
    for key in ("X", "method", "refine", "rotation_rms_deg", "translation_rms", "stations",
                "outliers"):
        assert key in data
    assert np.abs(np.array(data["X"]) - X_TRUE).max() < 1e-6
    assert data["method"] == "tsai" and data["refine"] == "lm"
    assert len(data["stations"]) == 9 and set(data["stations"][0]) == {"rotation_deg",
                                                                       "translation"}
    assert data["outliers"] == []
    assert json.loads(out.read_text())["X"] == data["X"]


def test_handeye_yaml_and_refine_none(tmp_path, capsys):
    path = _write_pairs(tmp_path, "yml")
    assert main(["handeye", str(path), "--refine", "none", "--method", "daniilidis"]) == 0
    text = capsys.readouterr().out
    assert "cam2flange" in text and "outliers (0-based stations): none" in text


def test_handeye_bundled_camodocal(capsys):
    assert main(["handeye", "handeye-camodocal", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["setup"] == "eye-to-hand" and 36 in data["outliers"]
    assert len(data["stations"]) == 42


def test_handeye_bad_input_exit_2(tmp_path, capsys):
    assert main(["handeye", str(tmp_path / "missing.csv")]) == 2
    assert "missing.csv" in capsys.readouterr().err
    path = _write_pairs(tmp_path)
    assert main(["handeye", str(path), "--method", "magic"]) == 2
    err = capsys.readouterr().err
    assert "method" in err and "park" in err and len(err.strip().splitlines()) == 1
    bad = tmp_path / "bad.csv"
    lines = path.read_text().splitlines()
    lines[2] = lines[2].replace(lines[2].split(",")[0], "abc", 1)
    bad.write_text("\n".join(lines) + "\n")
    assert main(["handeye", str(bad)]) == 2
    assert "row 2" in capsys.readouterr().err


def test_handeye_poses_star_and_random(tmp_path, capsys):
    out = tmp_path / "poses.csv"
    assert main(["handeye-poses", "--distance", "380", "--radius", "60", "--count", "19",
                 "--out", str(out)]) == 0
    cols = read_table(out, [f"camera_{c}" for c in ("x", "y", "z", "qw", "qx", "qy", "qz")])
    assert cols["camera_z"].shape == (19,) and np.allclose(cols["camera_z"], 380.0)
    pq = np.column_stack([cols[f"camera_{c}"] for c in ("x", "y", "z", "qw", "qx", "qy", "qz")])
    T = transform_from_pq(pq)
    z = T[:, :3, 2]
    p = T[:, :3, 3]
    assert np.allclose(z, -p / np.linalg.norm(p, axis=1, keepdims=True), atol=1e-9)
    r1 = tmp_path / "r1.csv"
    r2 = tmp_path / "r2.csv"
    for r in (r1, r2):
        assert main(["handeye-poses", "--distance", "380", "--radius", "60", "--count", "7",
                     "--scheme", "random", "--seed", "4", "--out", str(r)]) == 0
    assert r1.read_text() == r2.read_text()
    assert main(["handeye-poses", "--distance", "380", "--radius", "60", "--count", "7",
                 "--scheme", "spiral", "--out", str(r1)]) == 2
    assert main(["handeye-poses", "--distance", "380", "--radius", "60", "--count", "2",
                 "--out", str(tmp_path / "x.csv")]) == 2
    assert not (tmp_path / "x.csv").exists()
