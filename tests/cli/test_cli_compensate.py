"""``kinecal compensate`` (DESIGN section 4 contract) and ``kinecal stewart ik`` with a
calibrated geometry (the parallel CMM's compensation)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from kinecal.calibration.serial.simulate import random_configurations, read_truth
from kinecal.cli import main
from kinecal.io.geometry import load_geometry
from kinecal.io.models import load_model
from kinecal.spatial import quaternion_from_matrix


def _read(path):
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: [r[k] for r in rows] for k in rows[0]}


def _write(path, header, rows):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return path


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """UR5 simulated with random errors, calibrated: result JSON, model file, truth."""
    d = tmp_path_factory.mktemp("comp")
    assert main(["simulate", "ur5", "--poses", "60", "--noise", "0.01", "--seed", "1",
                 "--out", str(d / "meas.csv"), "--truth-out", str(d / "truth.json")]) == 0
    assert main(["calibrate", "ur5", str(d / "meas.csv"), "--out", str(d / "result.json"),
                 "--model-out", str(d / "ur5-cal.yaml"), "--quiet"]) == 0
    return d


@pytest.fixture
def program(tmp_path):
    model = load_model("ur5")
    q = np.round(np.degrees(random_configurations(model, 12, np.random.default_rng(3)) * 0.7), 6)
    rows = [[f"P{k}", *r, 250, "note, with comma"] for k, r in enumerate(q)]
    return _write(tmp_path / "prog.csv", ["label", "q1", "q2", "q3", "q4", "q5", "q6",
                                          "speed", "comment"], rows), q


def test_joint_program_from_a_model_file_and_a_result_json(calibrated, program, tmp_path,
                                                           capsys):
    path, q_deg = program
    out1, out2 = tmp_path / "c1.csv", tmp_path / "c2.csv"
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(path), "--out",
                 str(out1)]) == 0
    text = capsys.readouterr().out
    assert "compensated 12 joint-program rows (pose)" in text and "wrote 12 rows" in text
    assert main(["compensate", str(calibrated / "result.json"), str(path), "--nominal", "ur5",
                 "--out", str(out2), "--quiet"]) == 0
    a, b = _read(out1), _read(out2)
    # the program's own columns come back in place, untouched except the joints
    assert list(a)[:9] == ["label", "q1", "q2", "q3", "q4", "q5", "q6", "speed", "comment"]
    assert a["label"] == [f"P{k}" for k in range(12)] and set(a["comment"]) == {
        "note, with comma"}
    for c in ("dq1", "correction", "correction_angle", "converged", "residual",
              "residual_angle", "status"):
        assert c in a
    qa = np.array([[float(a[f"q{i}"][r]) for i in range(1, 7)] for r in range(12)])
    qb = np.array([[float(b[f"q{i}"][r]) for i in range(1, 7)] for r in range(12)])
    np.testing.assert_allclose(qa, qb, atol=1e-9)  # model file and result JSON agree
    dq = np.array([[float(a[f"dq{i}"][r]) for i in range(1, 7)] for r in range(12)])
    np.testing.assert_allclose(qa - q_deg, dq, atol=1e-9)  # degrees, like the program
    # the true arm at the compensated joints reaches the program's intent
    model = load_model("ur5")
    true = read_truth(calibrated / "truth.json", model)
    intended = model.positions(np.radians(q_deg))
    ok = np.array(a["converged"]) == "true"
    assert ok.mean() >= 0.9
    after = np.linalg.norm(model.positions(np.radians(qa), true) - intended, axis=1)[ok]
    before = np.linalg.norm(model.positions(np.radians(q_deg), true) - intended, axis=1)
    assert after.max() < 0.05 and before.mean() > 2.0
    assert float(max(a["residual"][k] for k in np.flatnonzero(ok))) <= 1e-9


def test_calibrated_urdf_export_of_a_dh_model(calibrated, program, tmp_path, capsys):
    """Another convention than the nominal model: the calibrated UR5 exported to URDF
    (world -> tool, metres) compensates like its YAML model file."""
    path, _ = program
    urdf = tmp_path / "ur5-cal.urdf"
    assert main(["export", str(calibrated / "result.json"), "--out", str(urdf)]) == 0
    outs, ok = [], []
    for spec in (urdf, calibrated / "ur5-cal.yaml"):
        out = tmp_path / f"{spec.suffix[1:]}.csv"
        assert main(["compensate", str(spec), str(path), "--nominal", "ur5", "--out",
                     str(out), "--quiet"]) == 0
        c = _read(out)
        outs.append(np.array([[float(c[f"q{i}"][r]) for i in range(1, 7)]
                              for r in range(12)]))
        ok.append(np.array(c["converged"]) == "true")
    np.testing.assert_array_equal(ok[0], ok[1])
    assert ok[0].mean() >= 0.9
    np.testing.assert_allclose(outs[0][ok[0]], outs[1][ok[0]], atol=1e-8)
    capsys.readouterr()
    # without --nominal the URDF (named after the robot) does not say which model it is
    assert main(["compensate", str(urdf), str(path), "--out", str(tmp_path / "x.csv")]) == 2
    assert "--nominal" in capsys.readouterr().err


def test_cartesian_targets_with_seeds_and_filtered_targets(calibrated, tmp_path, capsys):
    model = load_model("ur5")
    q = random_configurations(model, 8, np.random.default_rng(4)) * 0.7
    T = model.fk(q)
    quat = quaternion_from_matrix(T[:, :3, :3])
    rows = [[*T[k, :3, 3], *quat[k], *np.degrees(q[k])] for k in range(8)]
    header = ["x", "y", "z", "qw", "qx", "qy", "qz", "q1", "q2", "q3", "q4", "q5", "q6"]
    path = _write(tmp_path / "targets.csv", header, rows)
    out = tmp_path / "t.csv"
    assert main(["compensate", str(calibrated / "result.json"), str(path), "--out", str(out),
                 "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["kind"] == "targets" and stats["outputs"] == "pose" and stats["rows"] == 8
    assert stats["warnings"] == [] or all("code" in w for w in stats["warnings"])
    t = _read(out)
    for c in ("filtered_x", "filtered_qw", "dq6", "correction", "status"):
        assert c in t
    np.testing.assert_allclose([float(v) for v in t["x"]], T[:, 0, 3], rtol=1e-12)
    qc = np.radians([[float(t[f"q{i}"][r]) for i in range(1, 7)] for r in range(8)])
    filt = np.array([[float(t[f"filtered_{c}"][r]) for c in "xyz"] for r in range(8)])
    np.testing.assert_allclose(filt, model.positions(qc), atol=1e-8)
    # position targets without seeds: a warning, still solved; --position-only
    pos = _write(tmp_path / "p.csv", ["x", "y", "z"], [list(r[:3]) for r in rows])
    assert main(["compensate", str(calibrated / "result.json"), str(pos), "--out",
                 str(tmp_path / "p-out.csv")]) == 0
    err = capsys.readouterr().err
    assert "no-seed-joints" in err
    assert "filtered_qw" not in _read(tmp_path / "p-out.csv")
    assert main(["compensate", str(calibrated / "result.json"), str(pos), "--out",
                 str(tmp_path / "p-out.csv"), "--strict"]) == 2
    assert "no-seed-joints" in capsys.readouterr().err


def test_rows_that_do_not_converge_are_kept_warned_and_strict_exits_2(calibrated, tmp_path,
                                                                      capsys, recwarn):
    # rows near singularities (random over +-180 deg) where the calibrated arm cannot reach
    # the full pose on the program's branch: found with the Python API, then run by the CLI
    from kinecal import compensate

    model = load_model("ur5")
    cal = load_model(calibrated / "ur5-cal.yaml")
    q = random_configurations(model, 300, np.random.default_rng(0))
    res = compensate(cal, model, joints=q)
    bad, good = np.flatnonzero(~res.converged), np.flatnonzero(res.converged)
    assert bad.size >= 1
    rows = np.degrees(q[[good[0], bad[0], good[1]]])
    path = _write(tmp_path / "prog.csv", ["q1", "q2", "q3", "q4", "q5", "q6"], rows)
    out = tmp_path / "c.csv"
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(path), "--out",
                 str(out)]) == 0
    err = capsys.readouterr().err
    c = _read(out)
    assert c["converged"] == ["true", "false", "true"] and c["status"][1] != "converged"
    assert "1 of 3 rows did not converge" in err and "[compensation-not-converged]" in err
    out.unlink()
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(path), "--out",
                 str(out), "--strict"]) == 2
    assert not out.exists()  # nothing written
    assert "compensation-not-converged" in capsys.readouterr().err
    # --position-only: the point alone is reachable
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(path), "--out",
                 str(out), "--position-only", "--quiet"]) == 0
    assert _read(out)["converged"] == ["true"] * 3 and "correction_angle" not in _read(out)


def test_another_arm_and_bad_input_exit_2(calibrated, program, tmp_path, capsys):
    path, _ = program
    out = tmp_path / "c.csv"
    cases = [
        ([str(calibrated / "ur5-cal.yaml"), str(path), "--nominal", "irb120"], "same arm"),
        ([str(calibrated / "result.json"), str(path), "--nominal", "puma560"], "ur5"),
        ([str(calibrated / "ur5-cal.yaml"), str(tmp_path / "missing.csv")], "missing.csv"),
        ([str(calibrated / "ur5-cal.yaml"), str(path), "--base", "tracker"], "--base"),
        ([str(calibrated / "nothing.yaml"), str(path)], "CALIBRATED"),
    ]
    for args, needle in cases:
        assert main(["compensate", *args, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("kinecal: error:") and needle in err and err.count("\n") == 1
    bad = _write(tmp_path / "bad.csv", ["q1", "q2", "q3", "q4", "q5", "q6"],
                 [[0, 0, 0, 0, 0, 0], [0, 0, "nan", 0, 0, 0]])
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(bad), "--out",
                 str(out)]) == 2
    assert "row 2" in capsys.readouterr().err
    quat = _write(tmp_path / "quat.csv", ["x", "y", "z", "qw", "qx", "qy", "qz"],
                  [[400, 0, 500, 1, 0, 0, 0], [400, 0, 500, 0.5, 0, 0, 0]])
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(quat), "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert "quat.csv, row 2" in err and "unit quaternion" in err
    five = _write(tmp_path / "five.csv", ["q1", "q2", "q3", "q4", "q5"], [[0] * 5])
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(five), "--out",
                 str(out)]) == 2
    assert "q6" in capsys.readouterr().err
    # an output over an input is refused before any work
    assert main(["compensate", str(calibrated / "ur5-cal.yaml"), str(path), "--out",
                 str(path)]) == 2
    assert "overwrite" in capsys.readouterr().err
    # a model file without a name that leads to its nominal needs --nominal
    renamed = tmp_path / "arm.yaml"
    renamed.write_text((calibrated / "ur5-cal.yaml").read_text().replace(
        "name: ur5-calibrated", "name: cell-3-arm"))
    assert main(["compensate", str(renamed), str(path), "--out", str(out)]) == 2
    assert "--nominal" in capsys.readouterr().err
    assert main(["compensate", str(renamed), str(path), "--nominal", "ur5", "--out", str(out),
                 "--quiet"]) == 0


def test_stewart_ik_with_a_calibrated_geometry_is_the_cmms_compensation(tmp_path, capsys):
    d = tmp_path
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "40", "--errors", "1e-3",
                 "--seed", "3", "--out", str(d / "data.csv"), "--truth-out",
                 str(d / "true.yaml")]) == 0
    assert main(["stewart", "calibrate", "liu2008-cmm", str(d / "data.csv"),
                 "--geometry-out", str(d / "cal.yaml")]) == 0
    capsys.readouterr()
    pose = "0.01,0.02,0.93,2.0,-1.5,3.0"
    (d / "poses.csv").write_text("x,y,z,alpha,beta,gamma\n" + pose + "\n")
    legs = {}
    for name, geom in (("nominal", "liu2008-cmm"), ("calibrated", str(d / "cal.yaml"))):
        assert main(["stewart", "ik", geom, str(d / "poses.csv")]) == 0
        out = _read_text(capsys.readouterr().out)
        legs[name] = np.array([float(out[f"l{i}"][0]) for i in range(1, 7)])
    true = load_geometry(d / "true.yaml")
    from kinecal.kinematics.stewart.platform import degrees_to_radians

    want = degrees_to_radians(np.array([[float(v) for v in pose.split(",")]]))
    reached = {k: true.forward(v[None], x0=want).poses[0] for k, v in legs.items()}
    miss = {k: np.linalg.norm(v[:3] - want[0, :3]) for k, v in reached.items()}
    assert miss["nominal"] > 1e-4 and miss["calibrated"] < 1e-5
    np.testing.assert_allclose(legs["calibrated"], load_geometry(d / "cal.yaml").inverse(want)[0])


def _read_text(text):
    rows = list(csv.DictReader(text.splitlines()))
    return {k: [r[k] for r in rows] for k in rows[0]}


def test_urdf_arm_calibrated_exported_and_compensated(tmp_path, capsys):
    """A URDF arm (ABB IRB 140 of rtb-data): simulate, calibrate, export the calibrated
    URDF, compensate a program with it against the nominal URDF (--base-link, --tip-link)."""
    from importlib import resources

    from kinecal.calibration.serial.simulate import read_truth

    irb140 = str(resources.files("rtbdata") / "xacro" / "abb_irb140_description" / "urdf"
                 / "irb140.urdf")
    links = ["--base-link", "base_link", "--tip-link", "tool0"]
    sim, truth, res = tmp_path / "sim.csv", tmp_path / "truth.json", tmp_path / "r.json"
    assert main(["simulate", irb140, *links, "--poses", "60", "--seed", "5", "--noise",
                 "1e-6", "--out", str(sim), "--truth-out", str(truth)]) == 0
    assert main(["calibrate", irb140, str(sim), *links, "--out", str(res), "--quiet"]) == 0
    cal = tmp_path / "irb140-cal.urdf"
    assert main(["export", str(res), "--nominal", irb140, "--out", str(cal)]) == 0
    model = load_model(irb140, base_link="base_link", tip_link="tool0")
    q = random_configurations(model, 10, np.random.default_rng(6)) * 0.6
    prog = _write(tmp_path / "p.csv", [f"q{i}" for i in range(1, 7)], np.degrees(q))
    out = tmp_path / "c.csv"
    capsys.readouterr()
    assert main(["compensate", str(cal), str(prog), "--nominal", irb140, *links,
                 "--out", str(out), "--position-only", "--quiet"]) == 0
    c = _read(out)
    assert c["converged"] == ["true"] * 10
    qc = np.radians([[float(c[f"q{i}"][r]) for i in range(1, 7)] for r in range(10)])
    true = read_truth(truth, model)
    before = np.linalg.norm(model.positions(q, true) - model.positions(q), axis=1)
    after = np.linalg.norm(model.positions(qc, true) - model.positions(q), axis=1)
    assert before.mean() > 1e-4 and after.max() < 1e-5  # metres: 0.1 mm -> 10 um
    assert main(["compensate", str(res), str(prog), "--nominal", irb140, *links,
                 "--out", str(out), "--position-only", "--quiet"]) == 0  # the result JSON
    c2 = _read(out)
    q2 = np.radians([[float(c2[f"q{i}"][r]) for i in range(1, 7)] for r in range(10)])
    np.testing.assert_allclose(q2, qc, atol=1e-9)
    assert main(["compensate", "ur5-nothing.yaml", str(prog), "--base-link", "x",
                 "--out", str(out)]) == 2


def test_the_readme_tutorial_steps(tmp_path, capsys, monkeypatch):
    """README steps 3-4: the IRB-120 simulated inside its wide tolerance box (errors up to
    2.9 deg per angle, ~35 mm), calibrated, then its program compensated."""
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "irb120", "--poses", "60", "--noise", "0.01", "--seed", "1",
                 "--out", "meas.csv", "--truth-out", "truth.json"]) == 0
    assert main(["calibrate", "irb120", "meas.csv", "--out", "result.json", "--model-out",
                 "irb120-calibrated.yaml", "--quiet"]) == 0
    (tmp_path / "program.csv").write_text(
        "q1,q2,q3,q4,q5,q6\n0,0,0,0,30,0\n10,20,-30,40,50,60\n-45,10,20,-60,45,90\n")
    capsys.readouterr()
    assert main(["compensate", "irb120-calibrated.yaml", "program.csv", "--out",
                 "program-compensated.csv"]) == 0
    text = capsys.readouterr().out
    assert "compensated 3 joint-program rows (pose): 3 converged" in text
    (tmp_path / "points.csv").write_text("x,y,z\n450,0,550\n400,150,500\n")
    assert main(["compensate", "result.json", "points.csv", "--out",
                 "points-compensated.csv"]) == 0
    assert "2 converged" in capsys.readouterr().out
    model = load_model("irb120")
    true = read_truth(tmp_path / "truth.json", model)
    c = _read(tmp_path / "points-compensated.csv")
    qc = np.radians([[float(c[f"q{i}"][r]) for i in range(1, 7)] for r in range(2)])
    np.testing.assert_allclose(model.positions(qc, true), [[450, 0, 550], [400, 150, 500]],
                               atol=0.05)  # the true arm: within the calibration's accuracy


def test_tool_option(calibrated, program, tmp_path, capsys):
    """--tool nominal: the program's tool on the calibrated arm (a result JSON or model
    file of the nominal model); a calibrated URDF is another description: refused."""
    path, _ = program
    out = tmp_path / "t.csv"
    assert main(["compensate", str(calibrated / "result.json"), str(path), "--tool",
                 "nominal", "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["tool"] == "nominal"
    assert main(["compensate", str(calibrated / "result.json"), str(path), "--tool",
                 "flange", "--out", str(tmp_path / "u.csv")]) == 2
    assert "option --tool" in capsys.readouterr().err
    urdf = tmp_path / "ur5-cal.urdf"
    assert main(["export", str(calibrated / "result.json"), "--out", str(urdf)]) == 0
    assert main(["compensate", str(urdf), str(path), "--nominal", "ur5", "--tool", "nominal",
                 "--out", str(tmp_path / "v.csv")]) == 2
    assert "nominal model's parameters" in capsys.readouterr().err
    assert not (tmp_path / "u.csv").exists() and not (tmp_path / "v.csv").exists()
