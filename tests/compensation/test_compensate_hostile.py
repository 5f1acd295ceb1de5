"""Compensation and IK on what a user actually feeds them: program rows beyond the joint
limits, radians in a degree program, rows that cannot converge, and a calibration with
several tracker targets compensated for the program's own tool."""

from __future__ import annotations

import csv
import dataclasses

import numpy as np
import pytest

from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.cli import main
from kinecal.compensation.api import compensate
from kinecal.io.measurements import write_measurements
from kinecal.io.models import load_model, save_model
from kinecal.kinematics.serial.ik import solve_ik


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def ur5_result(tmp_path_factory):
    d = tmp_path_factory.mktemp("hostile")
    assert main(["simulate", "ur5", "--poses", "50", "--noise", "0.01", "--seed", "4",
                 "--out", str(d / "meas.csv"), "--quiet"]) == 0
    assert main(["calibrate", "ur5", str(d / "meas.csv"), "--out", str(d / "r.json"),
                 "--quiet"]) == 0
    return d / "r.json"


def test_a_step_across_a_joint_limit_wraps_by_the_fewest_turns():
    """UR5 joints span +-360 deg: a step across +360 went to -360 + eps (two turns away
    from the seed) instead of eps."""
    model = load_model("ur5")
    seed = np.radians([[359.9, -80, 60, 20, 50, 60]])
    goal = np.radians([[360.5, -80, 60, 20, 50, 60]])  # the same pose as q1 = 0.5 deg
    res = solve_ik(model, model.fk(goal), seed)
    assert res.converged.all()
    np.testing.assert_allclose(np.degrees(res.q[0, 0]), 0.5, atol=1e-6)


def test_program_rows_beyond_the_limits_move_by_one_turn(ur5_result, tmp_path, capsys):
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3,q4,q5,q6\n370,-80,60,20,50,60\n-400,-80,60,20,50,60\n"
                    "10,-80,60,20,50,400\n")
    out = tmp_path / "o.csv"
    assert main(["compensate", str(ur5_result), str(prog), "--out", str(out)]) == 0
    assert "[joints-outside-limits]" in capsys.readouterr().err
    rows = _rows(out)
    assert all(r["converged"] == "true" for r in rows)
    # each joint moves by one turn plus the correction (it moved by two: q1 370 -> -350)
    np.testing.assert_allclose([float(r["q1"]) for r in rows], [10, -40, 10], atol=2.0)
    np.testing.assert_allclose(float(rows[2]["q6"]), 40, atol=2.0)
    assert max(abs(float(r[f"dq{j}"])) for r in rows for j in range(1, 7)) < 362


def test_radians_in_a_degree_program_warn(ur5_result, tmp_path, capsys):
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3,q4,q5,q6\n0.1,-1.2,1.0,0.3,0.8,1.0\n0.2,-1.1,0.9,0.1,0.9,0.5\n")
    out = tmp_path / "o.csv"
    assert main(["compensate", str(ur5_result), str(prog), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "[joint-units]" in err and "program joints" in err
    out.unlink()
    assert main(["compensate", str(ur5_result), str(prog), "--out", str(out), "--strict"]) == 2
    assert "[joint-units]" in capsys.readouterr().err and not out.exists()
    # a program in degrees does not warn
    prog.write_text("q1,q2,q3,q4,q5,q6\n10,-80,60,20,50,60\n20,-70,50,10,60,30\n")
    assert main(["compensate", str(ur5_result), str(prog), "--out", str(out)]) == 0
    assert "joint-units" not in capsys.readouterr().err


def test_summary_corrections_leave_out_rows_that_failed(ur5_result):
    """An unreachable target's "correction" is the distance to where the solver stopped:
    the summary said 'correction: mean 1320 mm' for one target out of reach."""
    from kinecal.cli.compensate import load_calibrated

    nom, cal = load_calibrated(str(ur5_result), None)
    q = np.radians([[10, -80, 60, 20, 50, 60]])
    T = nom.fk(q)[:, :3, 3]
    targets = np.vstack([T, T * 3.0])  # the second is out of reach
    with pytest.warns(Warning):
        res = compensate(cal, nom, targets=targets, seeds=np.vstack([q, q]))
    assert res.converged.tolist() == [True, False]
    text = res.summary()
    assert "correction (converged rows): mean" in text
    mean = float(text.split("correction (converged rows): mean ")[1].split()[0])
    assert mean == pytest.approx(res.correction[0], rel=1e-3) and mean < 10.0
    stats = res.stats()  # the JSON says the same, and says over which rows
    assert stats["correction_rows"] == "converged"
    assert stats["correction"]["mean"] == pytest.approx(res.correction[0], rel=1e-12)
    assert stats["joint_correction_rad"]["max"] == pytest.approx(
        np.abs(res.dq[0]).max(), rel=1e-12)


def test_several_markers_compensated_for_the_nominal_tool(tmp_path, capsys):
    """Three tracker targets on the flange, calibrated; the program's tool is the
    nominal one. compensate refused ('give models with the program's tool') even with
    --tool nominal; now the true arm, carrying the nominal tool, reaches the program's
    nominal poses at the compensated joints."""
    arm = dataclasses.replace(load_model("irb120"), fixed=("theta6", "d6", "a6", "alpha6"))
    points = {"A": [0.0, 0.0, 31.0], "B": [52.0, -3.0, 20.0], "C": [-4.0, 61.0, 25.0]}
    model = arm.with_markers(points)
    sim = simulate(model, 30, rng=7)  # noise-free, 30 configurations x 3 markers
    data = tmp_path / "three.csv"
    write_measurements(data, sim.data, model)
    save_model(arm, tmp_path / "arm.yaml")
    res = tmp_path / "r.json"
    assert main(["calibrate", str(tmp_path / "arm.yaml"), str(data), "--out", str(res),
                 "--quiet"]) == 0
    q = random_configurations(arm, 8, np.random.default_rng(8)) * 0.6
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(
        ",".join(repr(float(v)) for v in row) for row in np.degrees(q)) + "\n")
    out = tmp_path / "o.csv"
    base = ["compensate", str(res), str(prog), "--nominal", str(tmp_path / "arm.yaml"),
            "--out", str(out)]
    assert main(base) == 2
    err = capsys.readouterr().err
    assert "several markers" in err and "--tool nominal" in err and not out.exists()
    assert main([*base, "--tool", "nominal", "--quiet"]) == 0
    capsys.readouterr()
    rows = _rows(out)
    assert all(r["converged"] == "true" for r in rows)
    q_comp = np.radians([[float(r[f"q{j}"]) for j in range(1, 7)] for r in rows])
    # the true arm (the simulation's geometry) with the nominal tool
    p_true = arm.nominal
    for k, name in enumerate(arm.parameter_names):
        if not name.startswith("tool."):
            p_true[k] = sim.true_params[model.index([name])[0]]
    intended = arm.positions(q)
    before = np.linalg.norm(arm.positions(q, p_true) - intended, axis=1)
    after = np.linalg.norm(arm.positions(q_comp, p_true) - intended, axis=1)
    assert before.min() > 0.1 and after.max() < 1e-6, (before, after)


RAIL = """<?xml version="1.0"?>
<robot name="rail">
<link name="floor"/><link name="carriage"/>
<joint name="rail" type="prismatic"><parent link="floor"/><child link="carriage"/>
<origin xyz="0.1 0.2 0.5" rpy="0 0 0"/><axis xyz="1 0 0"/>
<limit lower="0" upper="4" effort="1" velocity="1"/></joint>
</robot>
"""


def test_a_linear_axis_is_recognised_as_its_own_calibration(tmp_path):
    """Tool points on a line leave the registration's turn about it free: a calibrated
    linear rail was refused as 'another arm' (tool frames 97 deg apart)."""
    from kinecal.compensation.same_arm import check_same_arm

    path = tmp_path / "rail.urdf"
    path.write_text(RAIL)
    nominal = load_model(path)
    p = nominal.nominal
    p[nominal.index(["base.rx", "base.ry", "tool.x", "tool.y", "tool.z"])] = [
        0.004, -0.003, 1e-3, -2e-3, 5e-4]
    reg = check_same_arm(nominal, nominal.with_params(p))
    assert reg.rotation.max() < 0.01 and reg.position.max() < 0.01


def test_a_compensated_program_given_back_is_refused_before_work(ur5_result, tmp_path,
                                                                 capsys):
    """The column clash was found after every row had been solved (and its warnings
    printed)."""
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n10,-80,60,20,50,60\n")
    out, again = tmp_path / "o.csv", tmp_path / "o2.csv"
    assert main(["compensate", str(ur5_result), str(prog), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["compensate", str(ur5_result), str(out), "--out", str(again)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "o.csv" in err and "output of kinecal compensate" in err
    assert "compensation-not-converged" not in err and not again.exists()
