"""Compensation with a calibrated model: a simulated arm whose true geometry is hidden from
the calibration, exact compensation with the true geometry, Cartesian targets and filtered
targets, refusal of another arm, warnings; the Stewart CMM's compensation."""

import numpy as np
import pytest

from kinecal import compensate
from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.calibration.stewart.calibrate import (
    calibrate_stewart,
    perturb_geometry,
    simulate_stewart,
)
from kinecal.diagnostics import KinecalWarning, collect
from kinecal.errors import InputError
from kinecal.io.geometry import load_geometry
from kinecal.io.models import load_model
from kinecal.kinematics.serial.ik import solve_ik
from kinecal.spatial import matrix_from_rpy, pose_errors, transform_from


@pytest.fixture(scope="module")
def study():
    """UR5 with random true errors (the model's tolerances), calibrated on 60 noisy poses
    (10 um), validated on 100 held-out poses; a held-out program of 200 random rows."""
    model = load_model("ur5")
    rng = np.random.default_rng(14)
    sim = simulate(model, 60, errors="random", noise=0.01, rng=rng)
    val = simulate(model, 100, errors=sim.true_params - model.nominal, noise=0.01, rng=rng)
    res = calibrate(model, sim.data, "lm", validate=val.data)
    true = model.with_params(sim.true_params)
    program = random_configurations(model, 200, rng)
    # the calibrated model's own validation error: measured (with noise) and noise-free
    model_error = np.linalg.norm(res.model.positions(val.data.q) - val.exact_xyz, axis=1)
    return model, true, res, program, model_error


def _reached(true, q, intended):
    return np.linalg.norm(true.positions(q) - intended, axis=1)


def test_compensated_program_on_the_true_arm_reaches_the_calibrated_accuracy(study):
    model, true, res, program, model_error = study
    intended = model.positions(program)  # what the program means
    before = _reached(true, program, intended)  # the true arm runs the program as is
    c = compensate(res, joints=program, outputs="position")
    assert c.converged.all() and c.kind == "joints"
    after = _reached(true, c.q, intended)  # every row, converged or not
    assert before.mean() > 3.0  # millimetres off before
    assert after.mean() <= 1.2 * model_error.mean()
    assert after.mean() <= 1.2 * res.val_after.mean()
    assert after.mean() < before.mean() / 200
    # the reported correction is the error the calibrated model predicts for the program
    np.testing.assert_allclose(c.error_before, _reached(res.model, program, intended))
    np.testing.assert_allclose(c.correction, c.error_before, rtol=0.05, atol=1e-3)
    np.testing.assert_allclose(c.dq, c.q - program)
    assert c.residual.max() <= 1e-9


def test_pose_compensation_converged_rows_and_flagged_rest(study):
    model, true, res, program, model_error = study
    with pytest.warns(KinecalWarning):
        c = compensate(res, joints=program)  # 6 joints: the full pose by default
    assert c.outputs == "pose"
    # random programs over +-180 deg include folded and stretched elbows and flat wrists;
    # near those, the calibrated arm cannot reach the full pose on the program's branch:
    # such rows end at the singularity and are flagged, never marked converged
    assert c.converged.mean() >= 0.85
    assert (c.ik.condition[~c.converged] > 1e6).all()
    ok = c.converged
    after = _reached(true, c.q, model.positions(program))
    assert after[ok].mean() <= 1.2 * model_error.mean()
    assert (c.residual[ok] <= 1e-9).all() and (c.residual_rotation[ok] <= 1e-9).all()
    bad = ~ok
    assert set(c.status[bad]) <= {"unreachable", "joint-limit", "max-iterations"}
    with collect() as found:
        compensate(res, joints=program)
    codes = {d.code for d in found}
    assert "compensation-not-converged" in codes
    msg = next(d.message for d in found if d.code == "compensation-not-converged")
    assert f"{int(bad.sum())} of 200 rows did not converge" in msg


def test_compensation_with_the_true_geometry_is_exact():
    model = load_model("irb120")
    rng = np.random.default_rng(3)
    true_params = model.nominal + np.where(model.is_angle(), 1e-3, 0.2) * rng.normal(
        size=model.n_params)
    q = random_configurations(model, 100, rng) * 0.8
    c = compensate(true_params, model, joints=q)
    T_true = model.fk(c.q, true_params)
    rot, pos = pose_errors(T_true[c.converged], model.fk(q)[c.converged])
    assert pos.max() <= 1e-9 and rot.max() <= 1e-9
    # rows close to the elbow singularity (q3 near -77 deg, arm stretched) can be out of
    # the true arm's reach on their branch: they end at the singularity, flagged
    assert c.converged.mean() >= 0.9
    assert (c.ik.condition[~c.converged] > 1e6).all()
    assert (np.abs(np.degrees(q[~c.converged, 2]) + 77.0) < 8.0).all()
    again = compensate(true_params, model, joints=q)
    np.testing.assert_array_equal(again.q, c.q)


def test_cartesian_targets_filtered_for_a_nominal_controller(study):
    model, true, res, _, model_error = study
    rng = np.random.default_rng(5)
    q_seed = random_configurations(model, 100, rng)
    T = model.fk(q_seed)
    pq = np.column_stack([T[:, :3, 3], _quat(T)])
    c = compensate(res, targets=pq, seeds=q_seed + rng.normal(0, 0.01, q_seed.shape))
    assert c.kind == "targets" and c.outputs == "pose" and c.nominal_converged.all()
    ok = c.converged
    assert ok.mean() >= 0.85 and (c.ik.condition[~ok] > 1e6).all()
    # the true arm at the joints to command reaches the targets as well as calibrated
    assert _reached(true, c.q, T[:, :3, 3])[ok].mean() <= 1.2 * model_error.mean()
    # the filtered targets are the nominal model's poses at those joints: a controller
    # running its nominal model, sent the filtered targets, commands the same joints
    np.testing.assert_allclose(c.filtered, model.fk(c.q), atol=1e-9)
    back = solve_ik(model, c.filtered[ok], c.q[ok] + 1e-3)
    np.testing.assert_allclose(back.q, c.q[ok], atol=1e-8)
    # position targets: tool points only
    p = compensate(res, targets=T[:, :3, 3], seeds=q_seed, outputs=None)
    assert p.outputs == "position" and p.filtered.shape == (100, 3)
    assert p.converged.mean() >= 0.98


def test_targets_without_seeds_warn_and_solve():
    model = load_model("ur5")
    rng = np.random.default_rng(8)
    params = model.nominal + np.where(model.is_angle(), 2e-3, 0.3) * rng.normal(
        size=model.n_params)
    pts = model.positions(random_configurations(model, 40, rng))
    with collect() as found:
        c = compensate(params, model, targets=pts)
    assert "no-seed-joints" in {d.code for d in found}
    assert c.converged.all() and c.nominal_converged.all()
    np.testing.assert_allclose(model.positions(c.q, params), pts, atol=1e-9)


def test_another_arm_is_refused_and_a_far_base_warned():
    ur5 = load_model("ur5")
    q = np.zeros((2, 6)) + 0.5
    with pytest.raises(InputError, match="same arm"):
        compensate(load_model("irb120"), ur5, joints=q)
    with pytest.raises(InputError, match="same arm"):
        compensate(load_model("puma560"), ur5, joints=q)  # dh, 6 joints: other values
    p = ur5.nominal
    p[ur5.index(["a2"])] += 300.0  # 300 mm: not a calibration
    with pytest.raises(InputError, match="tool points differ by up to"):
        compensate(ur5.with_params(p), ur5, joints=q)
    with pytest.raises(InputError, match="nominal"):
        compensate(ur5, joints=q)
    with pytest.raises(InputError, match="either"):
        compensate(ur5.nominal, ur5)
    far = ur5.nominal
    far[ur5.index(["base.x", "base.rz"])] = [2500.0, 1.2]  # a laser tracker's frame
    with collect() as found:
        compensate(far, ur5, joints=q, base="nominal")
    assert "base-frame-far" not in {d.code for d in found}
    with collect() as found:
        compensate(far, ur5, joints=q)
    assert "base-frame-far" in {d.code for d in found}
    with collect() as found:
        compensate(ur5.nominal, ur5, joints=np.full((1, 6), 7.0))
    assert "joints-outside-limits" in {d.code for d in found}


def _quat(T):
    from kinecal.spatial import quaternion_from_matrix

    return quaternion_from_matrix(T[:, :3, :3])


def test_stewart_compensation_calibrated_legs_reach_the_desired_poses():
    """Legs computed with the calibrated geometry put the TRUE machine at the desired poses
    far better than legs computed with the nominal geometry."""
    nominal = load_geometry("liu2008-cmm")
    rng = np.random.default_rng(4)
    true = perturb_geometry(nominal, 1e-3, rng)  # 1 mm errors on all 42 parameters
    data = simulate_stewart(true, 60, rng=rng)  # 1 um / 1 arcsec measurement noise
    cal = calibrate_stewart(nominal, data).geometry
    desired = nominal.random_poses(300, rng)  # held-out poses the user wants, with legs
    lo, hi = nominal.leg_range  # away from the range ends (the machine differs by ~1 mm)
    legs = nominal.inverse(desired)
    desired = desired[((legs > lo + 5e-3) & (legs < hi - 5e-3)).all(axis=1)][:200]
    assert len(desired) == 200
    Td = transform_from(matrix_from_rpy(desired[:, 3:]), desired[:, :3])
    errors = {}
    for name, geom in (("nominal", nominal), ("calibrated", cal)):
        legs = geom.inverse(desired)  # what `kinecal stewart ik GEOMETRY` commands
        reached = true.forward(legs, x0=desired, on_failure="flag")
        assert reached.converged.all()
        Tr = transform_from(matrix_from_rpy(reached.poses[:, 3:]), reached.poses[:, :3])
        errors[name] = pose_errors(Tr, Td)
    rot_n, pos_n = errors["nominal"]
    rot_c, pos_c = errors["calibrated"]
    assert pos_n.mean() > 1e-3  # millimetres off with the nominal geometry (m)
    assert pos_c.mean() < 1e-5  # micrometres with the calibrated one
    assert pos_c.mean() < pos_n.mean() / 100
    assert rot_c.mean() < rot_n.mean() / 100


def test_joint_error_calibrations_compensate_through_their_corrections(tmp_path):
    """A true arm with harmonic joint errors: the error-model calibration's compensation
    reaches the intent on it; its model file and result JSON work on the command line."""
    import dataclasses

    from kinecal.calibration.serial.error_model import calibrate_error_model
    from kinecal.cli import main
    from kinecal.kinematics.serial.joint_errors import joint_errors_for

    ur5 = load_model("ur5")
    model = dataclasses.replace(ur5, joint_errors=joint_errors_for(ur5, ("harmonic",), 1))
    e = np.zeros(model.n_params)
    e[model.index(["dq2.sin1", "dq3.cos1", "dq4.sin1"])] = [3e-4, -2e-4, 4e-4]
    e[:ur5.n_params] = simulate(ur5, 1, errors="random", rng=7).true_params - ur5.nominal
    sim = simulate(model, 300, errors=e, noise=0.005, rng=8)
    geo = calibrate(ur5, sim.data)
    res = calibrate_error_model(ur5, sim.data, "harmonic", harmonics=1)
    true = model.with_params(model.nominal + e)
    q = random_configurations(ur5, 150, np.random.default_rng(9)) * 0.6
    intended = ur5.positions(q)
    errs = {}
    for name, r in (("geometric", geo), ("harmonic", res)):
        c = compensate(r, joints=q, outputs="position")
        assert c.converged.all()
        errs[name] = _reached(true, c.q, intended).mean()
    assert errs["harmonic"] < 0.3 * errs["geometric"]
    assert errs["harmonic"] < 0.01  # mm: the noise floor of 5 um measurements
    # files: the calibrated model (with its joint_errors section) and the result JSON
    res.save_model(tmp_path / "cal.yaml")
    res.to_json(tmp_path / "r.json")
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(f"{v:.17g}" for v in row)
                                                     for row in np.degrees(q[:10])) + "\n")
    outs = []
    for spec in ("cal.yaml", "r.json"):
        out = tmp_path / f"c-{spec}.csv"
        assert main(["compensate", str(tmp_path / spec), str(prog), "--nominal", "ur5",
                     "--out", str(out), "--position-only", "--quiet"]) == 0
        outs.append(np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(6)))
    np.testing.assert_allclose(outs[0], outs[1], atol=1e-9)
    c = compensate(res, joints=q[:10], outputs="position")
    np.testing.assert_allclose(np.radians(outs[0]), c.q, atol=1e-12)


def test_report_section_shows_the_compensation_of_the_validation_poses(study, tmp_path):
    from kinecal.report.compensation import compensation_section

    _, _, res, _, _ = study
    text = compensation_section(res)
    c = compensate(res, joints=res.q_validation, diagnose=False)
    assert '<section id="compensation">' in text
    assert f"{int(c.converged.sum())} of {len(c)}" in text
    assert f"{c.correction.mean():.4g} / {c.correction.max():.4g}" in text
    assert "kinecal compensate" in text
    with collect() as found:  # the report does not raise the command's warnings
        compensation_section(res)
    assert not found
    html = res.report(tmp_path / "r.html").read_text()
    assert '<section id="compensation">' in html


def test_long_programs_in_blocks_give_the_same_bits(monkeypatch):
    import kinecal.compensation.api as comp

    model = load_model("ur5")
    rng = np.random.default_rng(12)
    params = model.nominal + np.where(model.is_angle(), 1e-3, 0.3) * rng.normal(
        size=model.n_params)
    q = random_configurations(model, 45, rng) * 0.7
    one = compensate(params, model, joints=q, diagnose=False)
    calls = []
    monkeypatch.setattr(comp, "BLOCK", 10)
    blocks = compensate(params, model, joints=q, diagnose=False,
                        progress=lambda done, total: calls.append((done, total)))
    assert calls == [(10, 45), (20, 45), (30, 45), (40, 45), (45, 45)]
    for f in ("q", "converged", "status", "correction", "residual"):
        np.testing.assert_array_equal(getattr(blocks, f), getattr(one, f))


def test_prismatic_joint_corrections_are_lengths_not_degrees(tmp_path):
    """A SCARA quill: its correction is reported in the length unit, never as degrees."""
    path = tmp_path / "scara.yaml"
    path.write_text(
        "name: scara\nconvention: dh\nlength_unit: mm\nangle_unit: deg\njoints:\n"
        "  - {theta: 0, d: 400, a: 250, alpha: 0}\n  - {theta: 0, d: 0, a: 200, alpha: 180}\n"
        "  - {theta: 0, d: 0, a: 0, alpha: 0, type: prismatic}\n"
        "  - {theta: 0, d: 50, a: 0, alpha: 0}\ntool: [10, 0, 30]\n"
        "joint_limits: [[-143, 143], [-143, 143], [0, 150], [-180, 180]]\n"
        "tolerances: {length: 0.5, angle: 0.1}\n")
    model = load_model(path)
    true_params = model.nominal.copy()
    true_params[model.index(["d3"])] += 1.5  # the quill reads 1.5 mm short
    q = np.array([[0.2, 0.3, 100.0, 0.5], [-0.5, 0.7, 5.0, 0.0]])
    c = compensate(true_params, model, joints=q)
    assert c.converged.all()
    np.testing.assert_allclose(np.abs(c.dq[:, 2]), 1.5, atol=1e-6)
    rev, lin = c.joint_motion()
    np.testing.assert_allclose(lin, 1.5, atol=1e-6)
    assert np.degrees(rev.max()) < 0.01
    text = c.summary()
    assert "1.5 mm (prismatic)" in text and "85.94 deg" not in text
    assert c.stats()["joint_correction_length"]["max"] == pytest.approx(1.5, abs=1e-6)


def test_a_measured_target_is_not_the_programs_tool():
    """The calibration measured a tracker reflector 50 mm off the flange's tool point: by
    default the compensation warns (it would move the reflector onto the program's
    poses); tool='nominal' puts the program's tool on the calibrated arm, and the true arm
    carrying that tool then reaches the program's poses."""
    model = load_model("puma560")
    e = np.zeros(model.n_params)
    e[model.index(["theta2", "a2", "d3", "alpha3", "d4"])] = [1e-3, 0.3, -0.2, 1e-3, 0.25]
    e[model.index(["tool.x", "tool.y", "tool.z"])] = [40.0, -25.0, 30.0]  # the reflector
    sim = simulate(model, 60, errors=e, noise=0.0, rng=21)
    res = calibrate(model, sim.data)
    q = random_configurations(model, 40, np.random.default_rng(22)) * 0.6
    with collect() as found:
        compensate(res, joints=q)
    assert "tool-point-far" in [d.code for d in found]
    with collect() as found:
        c = compensate(res, joints=q, tool="nominal")
    assert "tool-point-far" not in [d.code for d in found]
    truth_with_tcp = sim.true_params.copy()
    idx = model.index(["tool.x", "tool.y", "tool.z"])
    truth_with_tcp[idx] = model.nominal[idx]
    ok = c.converged
    assert ok.mean() >= 0.9
    rot, pos = pose_errors(model.fk(c.q[ok], truth_with_tcp), model.fk(q[ok]))
    assert pos.max() < 1e-6 and rot.max() < 1e-9
    with pytest.raises(InputError, match="tool"):
        compensate(res, joints=q, tool="flange")
