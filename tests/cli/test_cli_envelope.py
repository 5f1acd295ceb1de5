"""The calibrated joint envelope in results, ``outside-calibrated-range`` in fk, compensate
and --validate, and the frictions of ``--error-model`` met on the UR10 set: ``--free
NAMES`` on a model's terms, marker columns, warnings worded and issued once."""

import dataclasses
import json

import numpy as np
import pytest

import kinecal
from kinecal import diagnostics
from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.cli import main
from kinecal.io.measurements import write_measurements
from kinecal.kinematics.serial.markers import with_markers

DEG = np.pi / 180


@pytest.fixture(scope="module")
def ur5():
    return kinecal.load_model("ur5")


def poses(model, n, seed, q1=(-60.0, 60.0)):
    rng = np.random.default_rng(seed)
    q = random_configurations(model, n, rng)
    q[:, 0] = rng.uniform(q1[0] * DEG, q1[1] * DEG, n)
    return q


def joints_csv(path, q):
    path.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(
        ",".join(repr(float(v)) for v in row) for row in np.degrees(q)) + "\n")
    return path


@pytest.fixture(scope="module")
def calibrated(ur5, tmp_path_factory):
    """A geometric calibration over q1 in -60 .. 60 deg: its result JSON and the poses."""
    tmp = tmp_path_factory.mktemp("env")
    truth = simulate(ur5, 200, errors="random", noise=0.01, q=poses(ur5, 200, 1), rng=1)
    write_measurements(tmp / "cal.csv", truth.data, ur5)
    assert main(["calibrate", "ur5", str(tmp / "cal.csv"), "--out", str(tmp / "r.json"),
                 "--quiet"]) == 0
    return tmp, truth


def test_result_stores_the_envelope_and_load_result_reads_it(ur5, calibrated):
    tmp, truth = calibrated
    data = json.loads((tmp / "r.json").read_text())
    env = data["envelope"]
    assert env["joints"] == [f"q{j}" for j in range(1, 7)]
    np.testing.assert_allclose(env["low"], np.degrees(truth.data.q.min(axis=0)), rtol=1e-12)
    np.testing.assert_allclose(env["high"], np.degrees(truth.data.q.max(axis=0)), rtol=1e-12)
    back = kinecal.load_result(tmp / "r.json")
    np.testing.assert_allclose(back.envelope.low, truth.data.q.min(axis=0), rtol=1e-12)
    res = kinecal.calibrate(ur5, truth.data)
    np.testing.assert_array_equal(res.envelope.high, truth.data.q.max(axis=0))
    # a result written before results stored it still loads, without an envelope
    del data["envelope"]
    (tmp / "old.json").write_text(json.dumps(data))
    assert kinecal.load_result(tmp / "old.json").envelope is None


def test_fk_warns_for_rows_beyond_and_names_joint_and_amount(ur5, calibrated, capsys):
    tmp, _ = calibrated
    inside = joints_csv(tmp / "in.csv", poses(ur5, 5, 2, (-50.0, 50.0)))
    assert main(["fk", "ur5", str(inside), "--params", str(tmp / "r.json")]) == 0
    assert "outside-calibrated-range" not in capsys.readouterr().err  # clean data: silent
    q = poses(ur5, 5, 3, (-50.0, 50.0))
    q[1, 0] = 100 * DEG  # 40 deg beyond a 120 deg span: named
    q[3, 0] = -100 * DEG
    q[4, 0] = 70 * DEG  # 10 deg beyond: within the edge margin (a quarter of the span)
    beyond = joints_csv(tmp / "out.csv", q)
    hi = json.loads((tmp / "r.json").read_text())["envelope"]["high"][0]
    assert main(["fk", "ur5", str(beyond), "--params", str(tmp / "r.json")]) == 0
    err = capsys.readouterr().err
    assert "[outside-calibrated-range]" in err and "2 of 5 rows (rows 2, 4)" in err
    lo = json.loads((tmp / "r.json").read_text())["envelope"]["low"][0]
    assert f"q1 in 2 rows, up to {max(lo + 100, 100 - hi):.3g} deg" in err
    assert main(["fk", "ur5", str(beyond), "--params", str(tmp / "r.json"), "--strict"]) == 2


def test_compensate_warns_for_program_rows_beyond(ur5, calibrated, capsys):
    tmp, _ = calibrated
    q = poses(ur5, 4, 4, (-40.0, 40.0))
    q[2, 0] = 120 * DEG
    program = joints_csv(tmp / "prog.csv", q)
    assert main(["compensate", str(tmp / "r.json"), str(program), "--out",
                 str(tmp / "comp.csv"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "compensated joints: 1 of 4 rows (rows 3)" in err
    inside = joints_csv(tmp / "prog2.csv", poses(ur5, 4, 4, (-40.0, 40.0)))
    assert main(["compensate", str(tmp / "r.json"), str(inside), "--out",
                 str(tmp / "comp2.csv"), "--quiet"]) == 0
    assert "outside-calibrated-range" not in capsys.readouterr().err


def test_validate_beyond_the_calibration_poses_warns(ur5, calibrated, capsys):
    tmp, truth = calibrated
    far = simulate(ur5, 30, errors=truth.true_params - ur5.nominal,
                   q=poses(ur5, 30, 5, (90.0, 150.0)), rng=5)
    write_measurements(tmp / "far.csv", far.data, ur5)
    near = simulate(ur5, 30, errors=truth.true_params - ur5.nominal,
                    q=poses(ur5, 30, 6, (-50.0, 50.0)), rng=6)
    near_q = np.clip(near.data.q, truth.data.q.min(axis=0), truth.data.q.max(axis=0))
    near = simulate(ur5, 30, errors=truth.true_params - ur5.nominal, q=near_q, rng=6)
    write_measurements(tmp / "near.csv", near.data, ur5)
    assert main(["calibrate", "ur5", str(tmp / "cal.csv"), "--validate", str(tmp / "far.csv"),
                 "--quiet"]) == 0
    assert "validation poses: 30 of 30 rows" in capsys.readouterr().err
    assert main(["calibrate", "ur5", str(tmp / "cal.csv"), "--validate",
                 str(tmp / "near.csv"), "--quiet"]) == 0
    assert "outside-calibrated-range" not in capsys.readouterr().err


def test_free_names_on_a_model_with_terms_frees_exactly_those(ur5, tmp_path, capsys):
    """Re-registering a calibrated error model on other poses: 9 free, not 9 plus every
    coefficient the model file declares."""
    sim = simulate(ur5, 150, errors="random", noise=0.01, q=poses(ur5, 150, 7), rng=7)
    write_measurements(tmp_path / "cal.csv", sim.data, ur5)
    assert main(["calibrate", "ur5", str(tmp_path / "cal.csv"), "--error-model", "harmonic",
                 "--harmonics", "1", "--model-out", str(tmp_path / "em.yaml"),
                 "--quiet"]) == 0
    other = simulate(ur5, 60, errors=sim.true_params - ur5.nominal, noise=0.01,
                     q=poses(ur5, 60, 8, (-170.0, -120.0)), rng=8)
    write_measurements(tmp_path / "other.csv", other.data, ur5)
    names = ["base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz", "tool.x",
             "tool.y", "tool.z"]
    assert main(["calibrate", str(tmp_path / "em.yaml"), str(tmp_path / "other.csv"),
                 "--free", ",".join(names), "--out", str(tmp_path / "reg.json"),
                 "--quiet"]) == 0
    err = capsys.readouterr().err
    res = json.loads((tmp_path / "reg.json").read_text())
    assert res["free"] == names
    coef = [n for n in res["parameters"] if n.startswith("dq")]
    assert coef and all(not res["parameters"][n]["free"] for n in coef)
    # the poses lie beyond the range the model's terms were fitted on: said so
    assert "calibration poses (the model's joint-error terms)" in err
    # and the result rebuilds the terms for fk --params
    joints = joints_csv(tmp_path / "q.csv", other.data.q[:3])
    assert main(["fk", str(tmp_path / "em.yaml"), str(joints), "--params",
                 str(tmp_path / "reg.json")]) == 0
    out = np.loadtxt(capsys.readouterr().out.splitlines()[1:], delimiter=",")
    np.testing.assert_allclose(out, other.data.xyz[:3], atol=0.1)


def test_marker_column_with_an_error_model_and_fk_params(ur5, tmp_path, capsys):
    """A marker column makes the markers (as the geometric path does); the result's
    terms rebuild with them for fk --params."""
    mm = with_markers(ur5, {"A": [0.0, 0.07, 31.0], "B": [40.0, 0.0, 20.0]})
    marker = np.random.default_rng(9).integers(0, 2, 200)
    sim = simulate(mm, 200, noise=0.005, rng=9, marker=marker)
    write_measurements(tmp_path / "m.csv", sim.data, mm)
    assert main(["calibrate", "ur5", str(tmp_path / "m.csv"), "--error-model", "harmonic",
                 "--harmonics", "1", "--out", str(tmp_path / "r.json"), "--quiet"]) == 0
    (tmp_path / "q.csv").write_text("q1,q2,q3,q4,q5,q6,marker\n" + "\n".join(
        ",".join(repr(float(v)) for v in np.degrees(q)) + f",{'AB'[k]}"
        for q, k in zip(sim.data.q[:4], marker[:4], strict=True)) + "\n")
    assert main(["fk", "ur5", str(tmp_path / "q.csv"), "--params",
                 str(tmp_path / "r.json")]) == 0
    out = np.loadtxt(capsys.readouterr().out.splitlines()[1:], delimiter=",")
    np.testing.assert_allclose(out, sim.data.xyz[:4], atol=0.05)


def test_error_model_warnings_once_and_worded_for_the_users_free_choice(ur5):
    """The geometric stage and the final fit both count few poses: one warning, the final
    fit's (it was issued twice, with the geometric and the final parameter counts)."""
    sim = simulate(ur5, 20, errors="random", noise=0.01, rng=10)
    with diagnostics.collect() as found:
        res = kinecal.calibrate_error_model(ur5, sim.data, "harmonic", harmonics=1)
    few = [d for d in found if d.code == "few-poses"]
    assert len(few) == 1 and f"for {len(res.free)} free parameters" in few[0].message
    assert len(res.free) > 23  # the geometric stage's count was another


def test_geometry_lost_to_the_terms_is_not_called_an_explicit_list():
    """UR10 with the T-Mac on the flange axis: compliance takes d5, alpha5, tool.z's
    effect at the solution; the user gave no free list (the message said 'the explicit
    free list frees 3 parameters')."""
    from kinecal.datasets import bundled_csv

    model = kinecal.load_model(bundled_csv("ur10-ipa:model"))
    data = kinecal.read_measurements("ur10-ipa:A", model)
    data = dataclasses.replace(data.subset(np.arange(0, len(data), 8)), time=None)
    with diagnostics.collect() as found:
        kinecal.calibrate_error_model(model, data, "compliance")
    lost = [d.message for d in found if d.code == "unidentifiable-free"]
    assert lost and "explicit free list" not in lost[0]
    assert "identifiable at the nominal geometry are not at the solution" in lost[0]
