"""The base and tool frames parametrised locally about their nominal orientation: full rank
whatever the nominal angles (a T-Mac at pitch -90 deg, a base at ry = 90 deg before a
prismatic joint), analytic Jacobian, exact file round trips, results written before."""

from __future__ import annotations

import json

import numpy as np
import pytest

import kinecal
from kinecal.calibration.serial.problem import resolve_free
from kinecal.io.models import load_model, save_model
from kinecal.kinematics.serial.frames import frame_pose, frame_transform, with_frame_transform
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import matrix_from_rpy, transform_from, transform_from_xyz_rpy

UR10 = [{"theta": 0.0, "d": 127.3, "a": 0.0, "alpha": np.pi / 2},
        {"theta": 0.0, "d": 0.0, "a": -612.0, "alpha": 0.0},
        {"theta": 0.0, "d": 0.0, "a": -572.3, "alpha": 0.0},
        {"theta": 0.0, "d": 163.941, "a": 0.0, "alpha": np.pi / 2},
        {"theta": 0.0, "d": 115.7, "a": 0.0, "alpha": -np.pi / 2},
        {"theta": 0.0, "d": 92.2, "a": 0.0, "alpha": 0.0}]
#: a Leica T-Mac on a UR10 flange (ipa-robot-accuracy series B): its frame at pitch -90 deg
TMAC = [0.0, 0.0, 109.0, np.pi / 2, -np.pi / 2, 0.0]


def _tmac(base=(2000.0, -1500.0, 100.0, 0.3, -0.2, 1.1)) -> SerialModel:
    return SerialModel("ur10-tmac", "dh", UR10, base=list(base), tool=TMAC, angle_unit="deg")


def test_tmac_at_pitch_minus_90_has_full_rank_and_is_recovered():
    model = _tmac()
    sim = kinecal.simulate(model, 60, orientation=True, rng=2)
    truth = kinecal.simulate(model, 60, orientation=True, rng=3, errors={
        "tool.x": 0.5, "tool.y": -0.4, "tool.z": 0.3, "tool.rx": 0.01, "tool.ry": -0.02,
        "tool.rz": 0.015, "base.x": 3.0, "base.rx": 0.02, "base.ry": -0.01, "base.rz": 0.03})
    tool = ["tool.x", "tool.y", "tool.z", "tool.rx", "tool.ry", "tool.rz"]
    base = ["base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz"]
    # every base and tool parameter identifiable (the absolute roll-pitch-yaw lost one of
    # each at pitch -90: rx and rz turn about one axis there)
    _, report = resolve_free(model, sim.data, tool + base)
    assert report.rank == 12 and report.condition_number < 100
    # with the arm: what stays unidentifiable is the D-H chain's own (the tool turning
    # about the flange's z and x axes is theta6 and alpha6), nothing of the gimbal
    _, report = resolve_free(model, sim.data, "all")
    # (d1, theta1 with the base; d2, d3 with d4; theta6, d6, a6 with the tool translation
    # and rotation about flange z; tool.ry with alpha6)
    assert report.condition_number < 100
    assert set(report.unidentifiable) == {"theta1", "d1", "d2", "d3", "theta6", "d6", "a6",
                                          "tool.ry"}
    res = kinecal.calibrate(model, truth.data, free=tool + base)
    idx = model.index(tool + base)
    np.testing.assert_allclose(res.params[idx], truth.true_params[idx], atol=1e-7)
    assert res.errors_after.max() < 1e-7


def test_base_at_ry_90_before_a_prismatic_joint_keeps_six_base_parameters():
    """The known defect: a prismatic first joint (or one not about the base z) with the
    base at ry = +-90 deg lost a base rotation with roll-pitch-yaw parameters."""
    joints = [{"theta": 0.0, "d": 0.0, "a": 0.0, "alpha": np.pi / 2, "type": "prismatic"},
              {"theta": 0.0, "d": 0.0, "a": 300.0, "alpha": 0.0},
              {"theta": 0.0, "d": 0.0, "a": 250.0, "alpha": 0.0}]
    for ry in (np.pi / 2, -np.pi / 2):
        model = SerialModel("gantry", "dh", joints, base=[100.0, 50.0, 20.0, 0.2, ry, 0.4],
                            tool=[10.0, 20.0, 30.0], joint_limits=[[0, 400], [-3, 3], [-3, 3]])
        sim = kinecal.simulate(model, 80, rng=1)
        _, report = resolve_free(model, sim.data, [f"base.{k}" for k in
                                                   ("x", "y", "z", "rx", "ry", "rz")])
        assert report.rank == 6, (ry, report.unidentifiable)


def test_local_base_jacobian_matches_central_differences():
    model = _tmac()
    rng = np.random.default_rng(5)
    q = rng.uniform(-2, 2, (7, 6))
    p = model.nominal + rng.normal(0, 1e-3, model.n_params)
    J = model.identification_jacobian(q, p, "pose")
    h = 1e-6
    for k in model.index(["base.rx", "base.ry", "base.rz", "tool.rx", "tool.ry", "tool.rz",
                          "base.x", "tool.z"]):
        dp = np.zeros(model.n_params)
        dp[k] = h
        Tp, Tm = model.fk(q, p + dp), model.fk(q, p - dp)
        np.testing.assert_allclose(J[:, :3, k], (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h),
                                   rtol=1e-6, atol=1e-6)
        dR = Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2)  # small rotation, fixed frame
        w = np.stack([dR[:, 2, 1] - dR[:, 1, 2], dR[:, 0, 2] - dR[:, 2, 0],
                      dR[:, 1, 0] - dR[:, 0, 1]], axis=1) / 2 / (2 * h)
        np.testing.assert_allclose(J[:, 3:, k], w, atol=1e-6)


def test_nominal_frames_and_their_local_errors():
    model = _tmac()
    B = transform_from_xyz_rpy(model.base)
    np.testing.assert_allclose(frame_transform(model), B, atol=1e-15)
    w = np.array([0.01, -0.02, 0.03])
    p = model.nominal
    p[model.index(["base.rx", "base.ry", "base.rz"])] = w
    expect = B @ transform_from(matrix_from_rpy(w), np.zeros(3))
    np.testing.assert_allclose(frame_transform(model, p), expect, atol=1e-15)
    # the chain composes the same base: fk at q = 0 with and without it
    q = np.zeros((1, 6))
    flange_in_base = np.linalg.solve(frame_transform(model, p), model.fk(q, p)[0])
    np.testing.assert_allclose(flange_in_base, np.linalg.solve(B, model.fk(q)[0]), atol=1e-9)
    # a wanted base put in the model's chart reproduces it
    T = transform_from_xyz_rpy([5.0, 6.0, 7.0, 0.4, 1.2, -0.3])
    np.testing.assert_allclose(frame_transform(model, with_frame_transform(model, p, T)), T,
                               atol=1e-12)
    np.testing.assert_allclose(frame_pose(model, None, "tool"), TMAC, atol=1e-12)


def test_model_file_round_trip_of_local_errors_is_exact(tmp_path):
    model = _tmac()
    rng = np.random.default_rng(3)
    p = model.nominal + rng.normal(0, 0.01, model.n_params)
    cal = model.with_params(p)
    assert len(cal.base) == 9 and len(cal.tool) == 9  # nominal pose, then the local error
    save_model(cal, tmp_path / "cal.yaml")
    back = load_model(tmp_path / "cal.yaml")
    np.testing.assert_allclose(back.nominal, p, rtol=0, atol=1e-12)
    q = rng.uniform(-1, 1, (5, 6))
    np.testing.assert_allclose(back.fk(q), cal.fk(q), atol=1e-9)
    # the nominal model itself writes 6 values, as before
    save_model(model, tmp_path / "nom.yaml")
    assert "- 0.0\n" in (tmp_path / "nom.yaml").read_text()
    assert len(load_model(tmp_path / "nom.yaml").base) == 6


def test_results_round_trip_and_older_results_still_load(tmp_path):
    model = _tmac()
    save_model(model, tmp_path / "tmac.yaml")
    model = load_model(tmp_path / "tmac.yaml")
    sim = kinecal.simulate(model, 40, orientation=True, rng=4)
    res = kinecal.calibrate(model, sim.data)
    res.to_json(tmp_path / "r.json")
    data = json.loads((tmp_path / "r.json").read_text())
    np.testing.assert_allclose(data["frames"]["base"]["calibrated"][:3],
                               frame_pose(model, res.params)[:3], atol=1e-9)
    loaded = kinecal.load_result(tmp_path / "r.json", model=tmp_path / "tmac.yaml")
    np.testing.assert_allclose(loaded.params, res.params, rtol=0, atol=1e-12)
    # a result written when base.rx .. rz and tool.rx .. rz held absolute roll-pitch-yaw
    old = dict(data)
    del old["frames"]
    old["parameters"] = {k: dict(v) for k, v in data["parameters"].items()}
    deg = np.degrees
    for which in ("base", "tool"):
        pose = frame_pose(model, res.params, which)
        nominal = frame_pose(model, None, which)
        for k, key in enumerate(("rx", "ry", "rz")):
            old["parameters"][f"{which}.{key}"]["identified"] = float(deg(pose[3 + k]))
            old["parameters"][f"{which}.{key}"]["nominal"] = float(deg(nominal[3 + k]))
    (tmp_path / "old.json").write_text(json.dumps(old))
    was = kinecal.load_result(tmp_path / "old.json", model=tmp_path / "tmac.yaml")
    q = sim.data.q[:10]
    np.testing.assert_allclose(was.model.fk(q), res.model.fk(q), atol=1e-8)


@pytest.mark.parametrize("bad", [[1, 2, 3, 4], [0] * 8, [0, 0, 0, 0, 0, float("nan")]])
def test_bad_frames_are_refused(bad):
    with pytest.raises(kinecal.InputError, match="base"):
        SerialModel("x", "dh", UR10, base=bad)
