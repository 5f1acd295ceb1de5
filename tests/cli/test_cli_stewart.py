"""``kinecal stewart ik|fk|simulate|calibrate`` (DESIGN section 4 contract)."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from kinecal.cli import main
from kinecal.io.geometry import load_geometry

TABLE3_LEGS = [0.750, 0.780, 0.800, 0.900, 0.870, 0.850]
TABLE3_POSE_DEG = [0.039860, 0.095930, 0.925235, -12.697325, 6.403095, 15.133206]


def _csv(text: str) -> dict[str, list[str]]:
    rows = list(csv.DictReader(io.StringIO(text)))
    return {k: [r[k] for r in rows] for k in rows[0]}


@pytest.fixture
def legs_csv(tmp_path):
    path = tmp_path / "legs.csv"
    path.write_text("l1,l2,l3,l4,l5,l6\n" + ",".join(map(str, TABLE3_LEGS)) + "\n")
    return path


def test_fk_newton_table3(legs_csv, capsys):
    assert main(["stewart", "fk", "liu2008-cmm", str(legs_csv)]) == 0
    out = _csv(capsys.readouterr().out)
    got = [float(out[c][0]) for c in ("x", "y", "z", "alpha", "beta", "gamma")]
    np.testing.assert_allclose(got, TABLE3_POSE_DEG, atol=5e-7)
    assert out["converged"] == ["true"] and float(out["residual"][0]) < 1e-12


def test_fk_pso_json(legs_csv, capsys):
    assert main(["stewart", "fk", "liu2008-cmm", str(legs_csv), "--method", "pso", "--seed",
                 "2", "--json"]) == 0  # fmt: skip
    data = json.loads(capsys.readouterr().out)
    row = data["poses"][0]
    assert data["method"] == "pso" and row["converged"] is True and row["residual"] < 1e-6
    np.testing.assert_allclose([row["x"], row["y"], row["z"]], TABLE3_POSE_DEG[:3], atol=1e-6)


def test_fk_all_modes(legs_csv, capsys):
    assert main(["stewart", "fk", "liu2008-cmm", str(legs_csv), "--all"]) == 0
    out = _csv(capsys.readouterr().out)
    assert len(out["x"]) == 16 and out["mode"][-1] == "16"
    assert out["above"].count("true") == 8
    np.testing.assert_allclose(float(out["gamma"][0]), TABLE3_POSE_DEG[5], atol=5e-7)


def test_ik_fk_round_trip(tmp_path, capsys):
    poses = tmp_path / "poses.csv"
    poses.write_text(
        "x,y,z,alpha,beta,gamma\n" + ",".join(map(str, TABLE3_POSE_DEG)) + "\n0,0,0.97,0,0,0\n"
    )
    assert main(["stewart", "ik", "liu2008-cmm", str(poses)]) == 0
    legs = tmp_path / "legs.csv"
    legs.write_text(capsys.readouterr().out)
    assert main(["stewart", "fk", "liu2008-cmm", str(legs)]) == 0
    out = _csv(capsys.readouterr().out)
    np.testing.assert_allclose(float(out["z"][1]), 0.97, atol=1e-12)
    np.testing.assert_allclose(float(out["alpha"][0]), TABLE3_POSE_DEG[3], atol=1e-9)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("l1,l2,l3,l4,l5\n0.8,0.8,0.8,0.8,0.8\n", "missing column"),
        ("l1,l2,l3,l4,l5,l6\n0.8,0.8,nan,0.8,0.8,0.8\n", "row 1"),
        ("l1,l2,l3,l4,l5,l6\n0.8,0.8,0.8,0.8,0.8,0.8\n0.8,0.8,0.8,1.5,0.8,0.8\n", "row 2"),
        ("l1,l2,l3,l4,l5,l6\n0.75,0.97,0.75,0.97,0.75,0.97\n", "no real assembly"),
    ],
)
def test_fk_bad_input_exit_2(tmp_path, capsys, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    assert main(["stewart", "fk", "liu2008-cmm", str(path)]) == 2
    err = capsys.readouterr().err
    assert match in err and "bad.csv" in err and len(err.strip().splitlines()) == 1


def test_ik_unreachable_pose_and_unknown_geometry(tmp_path, capsys):
    path = tmp_path / "p.csv"
    path.write_text("x,y,z,alpha,beta,gamma\n0,0,0.97,0,0,0\n0,0,2.0,0,0,0\n")
    assert main(["stewart", "ik", "liu2008-cmm", str(path)]) == 2
    assert "row 2" in capsys.readouterr().err
    assert main(["stewart", "ik", "no-such-cmm", str(path)]) == 2
    assert "unknown geometry" in capsys.readouterr().err
    assert main(["stewart", "fk", "liu2008-cmm", str(path), "--method", "ga"]) == 2


def test_simulate_then_calibrate(tmp_path, capsys):
    data, val = tmp_path / "data.csv", tmp_path / "val.csv"
    truth, result, cal = tmp_path / "truth.yaml", tmp_path / "result.json", tmp_path / "cal.yaml"
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "60", "--seed", "1",
                 "--out", str(data), "--truth-out", str(truth)]) == 0  # fmt: skip
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "50", "--seed", "2",
                 "--errors", str(truth), "--out", str(val)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["stewart", "calibrate", "liu2008-cmm", str(data), "--validate", str(val),
                 "--out", str(result), "--geometry-out", str(cal)]) == 0  # fmt: skip
    assert "rank 42/42" in capsys.readouterr().out
    res = json.loads(result.read_text())
    assert res["rank"] == 42 and res["validation"]["after"]["rms"] < 3e-6
    assert res["validation"]["before"]["rms"] > 1e-4
    identified = load_geometry(cal).parameters
    true = load_geometry(truth).parameters
    assert np.abs(identified - true).max() < 2e-4  # from 1 mm errors
    assert np.abs(load_geometry("liu2008-cmm").parameters - true).max() > 5e-4


def test_simulate_quiet_and_strict(tmp_path, capsys):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "5", "--seed", "3",
                 "--out", str(a)]) == 0  # fmt: skip
    assert "wrote 5 poses" in capsys.readouterr().err
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "5", "--seed", "3",
                 "--out", str(b), "--quiet", "--strict"]) == 0  # fmt: skip
    assert capsys.readouterr().err == ""
    assert a.read_bytes() == b.read_bytes()  # same seed, same file


def test_calibrate_too_few_rows(tmp_path, capsys):
    data = tmp_path / "d.csv"
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "3", "--out", str(data)]) == 0
    assert main(["stewart", "calibrate", "liu2008-cmm", str(data)]) == 2
    assert "at least 8 distinct poses" in capsys.readouterr().err
