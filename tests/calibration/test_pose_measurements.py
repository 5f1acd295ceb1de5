"""Calibration from measured tool poses (position + orientation, 6-DoF instruments)."""

import json

import numpy as np
import pytest

import kinecal
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.calibration.serial.simulate import simulate
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.measurements import read_measurements, write_measurements


def test_jacobian_with_orientations_matches_finite_differences():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 12, errors="random", rng=0, orientation=True, angle_noise=0.02)
    pr = CalibrationProblem(m, sim.data, list(m.calibratable), rotation_weight=50.0)
    x = pr.x0 + 0.01  # far from the solution: residual rotations of several degrees
    assert pr.residuals(x).size == 6 * 12
    J = pr.jacobian(x)
    h = 1e-6
    Jn = np.column_stack([(pr.residuals(x + h * e) - pr.residuals(x - h * e)) / (2 * h)
                          for e in np.eye(pr.n_free)])
    assert np.abs(J - Jn).max() <= 1e-6 * np.abs(Jn).max()


def test_orientations_make_more_parameters_identifiable_and_recover_them():
    m = kinecal.load_model("irb120")
    cal = simulate(m, 30, errors="random", rng=1, orientation=True)
    val = simulate(m, 50, errors=cal.true_params - m.nominal, rng=2, orientation=True)
    res = kinecal.calibrate(m, cal.data, validate=val.data)
    # positions alone identify 20 of 25; orientations add theta5/alpha5 (or a5/d5), theta6, alpha6
    assert res.identifiability.rank == 24
    assert len(res.identifiability.unidentifiable) == 1
    assert res.identifiability.unidentifiable[0] in {"d2", "d3"}  # parallel axes: always one
    assert res.validation_stats["after"]["mean"] <= 1e-9
    rot = res.to_dict()["rotation_deg"]
    assert rot["validation"]["after"]["max"] <= 1e-9
    assert rot["calibration"]["before"]["mean"] > 1.0


def test_pose_csv_round_trip_and_errors(tmp_path):
    m = kinecal.load_model("ur5")
    sim = simulate(m, 5, errors="random", rng=3, orientation=True)
    write_measurements(tmp_path / "p.csv", sim.data, m)
    back = read_measurements(tmp_path / "p.csv", m)
    np.testing.assert_allclose(back.rotations, sim.data.rotations, atol=1e-12)
    lines = (tmp_path / "p.csv").read_text().splitlines()
    header = lines[0].split(",")
    # a missing quaternion column
    k = header.index("qz")
    cut = [",".join(c for i, c in enumerate(line.split(",")) if i != k) for line in lines]
    (tmp_path / "cut.csv").write_text("\n".join(cut) + "\n")
    with pytest.raises(InputError, match="qw, qx, qy, qz"):
        read_measurements(tmp_path / "cut.csv", m)
    # a non-unit quaternion in row 3
    cells = lines[3].split(",")
    cells[header.index("qw")] = "2.0"
    lines[3] = ",".join(cells)
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="unit quaternion") as info:
        read_measurements(tmp_path / "bad.csv", m)
    assert info.value.row == 3


def test_cli_simulates_and_calibrates_poses(tmp_path, capsys):
    d, t, v, out = (tmp_path / n for n in ("d.csv", "t.json", "v.csv", "r.json"))
    assert main(["simulate", "irb120", "--poses", "30", "--orientation", "--angle-noise", "0.001",
                 "--noise", "0.01", "--seed", "5", "--out", str(d), "--truth-out", str(t)]) == 0
    assert main(["simulate", "irb120", "--poses", "20", "--orientation", "--seed", "6",
                 "--errors", str(t), "--out", str(v)]) == 0
    assert main(["calibrate", "irb120", str(d), "--validate", str(v), "--out", str(out),
                 "--rotation-weight", "100", "--quiet"]) == 0
    res = json.loads(out.read_text())
    assert res["rank"] == 24
    assert res["rotation_deg"]["validation"]["after"]["mean"] < 0.01
    assert res["validation"]["after"]["mean"] < 0.05
    capsys.readouterr()
    assert main(["simulate", "irb120", "--poses", "5", "--angle-noise", "0.1",
                 "--out", str(tmp_path / "x.csv")]) == 2
    assert "--orientation" in capsys.readouterr().err


def test_report_shows_orientation_errors(tmp_path):
    m = kinecal.load_model("irb120")
    sim = simulate(m, 30, errors="random", rng=4, orientation=True, noise=0.01,
                   angle_noise=2e-4)
    res = kinecal.calibrate(m, sim.data)
    text = res.report(tmp_path / "r.html").read_text()
    assert "Orientation error" in text and "mean [deg]" in text
    assert "orientation error [deg]" in res.summary()
