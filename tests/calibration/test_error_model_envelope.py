"""Joint-error terms beyond the calibrated joint envelope: held at its edges, continuous
across a revolute joint's uncovered arc, analytic derivatives, cross-validation that also
tests extrapolation, and the half-range extrapolation that ``auto`` must not lose."""

import dataclasses

import numpy as np
import pytest

import kinecal
from kinecal.calibration.serial.cross_validation import (
    CVScore,
    blocked_folds,
    partitions,
    within_and_beyond,
)
from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors import JointErrors, joint_errors_for
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope, Retraction

DEG = np.pi / 180


@pytest.fixture(scope="module")
def ur5():
    return kinecal.load_model("ur5")


def with_terms(model, families, h, envelope):
    spec = joint_errors_for(model, families, h).within(envelope)
    return dataclasses.replace(model, joint_errors=spec)


def test_beyond_raw_and_modulo_a_turn():
    env = JointEnvelope((-100 * DEG, 0.0), (40 * DEG, 5.0), (True, False))
    q = np.array([[50 * DEG, 6.0], [-110 * DEG, -1.0], [0.0, 2.0], [300 * DEG, 2.0],
                  [-350 * DEG, 2.0]])
    d = env.beyond(q)
    np.testing.assert_allclose(d[:, 1], [1.0, -1.0, 0.0, 0.0, 0.0])  # prismatic: raw
    # revolute: 50 deg is 10 above 40; 300 deg = -60 (inside); -350 deg = 10 (inside)
    np.testing.assert_allclose(d[:, 0] / DEG, [10.0, -10.0, 0.0, 0.0, 0.0], atol=1e-12)
    raw = env.beyond(q, periodic=[False, False])
    np.testing.assert_allclose(raw[3:, 0] / DEG, [260.0, -250.0], atol=1e-12)
    # the uncovered arc 40 .. 260 deg: the nearer edge counts
    np.testing.assert_allclose(env.beyond(np.array([[200 * DEG, 0.0]]))[0, 0] / DEG, -60.0)
    full = JointEnvelope((-np.pi,), (np.pi,), (True,))
    assert full.full_turn()[0] and full.beyond(np.array([[7.0]]))[0, 0] == 0.0
    with pytest.raises(InputError):
        JointEnvelope((1.0,), (0.0,), (True,))
    with pytest.raises(InputError):
        JointEnvelope.of(np.zeros((0, 2)), (True, True))


def test_terms_are_held_at_the_edge_and_cross_the_gap_continuously(ur5):
    rng = np.random.default_rng(3)
    q = random_configurations(ur5, 300, rng)
    q[:, 1] = rng.uniform(-150 * DEG, -30 * DEG, 300)  # joint 2 over a third of a turn
    env = JointEnvelope.of(q, [True] * 6)
    model = with_terms(ur5, ["compliance", "harmonic", "scale"], 3, env)
    terms = model._joint_terms
    c = rng.normal(size=terms.n) * 1e-3
    scan = np.tile(q[0], (7200, 1))
    scan[:, 1] = np.linspace(-np.pi, np.pi, 7200)
    dq = terms.dq(scan, c)[:, 1]
    lo, hi = env.low[1], env.high[1]
    inside = (scan[:, 1] >= lo) & (scan[:, 1] <= hi)
    at = terms.dq(np.vstack([np.r_[q[0][:1], lo, q[0][2:]], np.r_[q[0][:1], hi, q[0][2:]]]),
                  c)[:, 1]
    # beyond the edges the correction never leaves the range of its two edge values
    assert dq[~inside].min() >= min(at) - 1e-15 and dq[~inside].max() <= max(at) + 1e-15
    # held at the edge (flat there: smoothstep), continuous all round the turn
    near = terms.dq(np.vstack([np.r_[q[0][:1], hi + 1e-3, q[0][2:]]]), c)[0, 1]
    assert abs(near - at[1]) < 1e-8
    step = np.abs(np.diff(dq)).max()
    assert step < 5 * np.abs(np.diff(dq[inside])).max() + 1e-12
    # a term fitted inside is the same function there as without an envelope (up to the
    # joint's constant, which the offset carries)
    free = with_terms(ur5, ["compliance", "harmonic", "scale"], 3, None)._joint_terms
    diff = free.dq(scan[inside], c)[:, 1] - dq[inside]
    np.testing.assert_allclose(diff, diff[0], atol=1e-15)


def test_derivatives_beyond_the_envelope_are_analytic(ur5):
    rng = np.random.default_rng(4)
    qc = random_configurations(ur5, 200, rng) * [0.4, 0.3, 0.5, 0.6, 0.4, 0.9]
    model = with_terms(ur5, ["compliance", "harmonic", "scale"], 2,
                       JointEnvelope.of(qc, [True] * 6))
    terms = model._joint_terms
    c = rng.normal(size=terms.n) * 1e-3
    q = rng.uniform(-np.pi, np.pi, (300, 6)) * 1.4  # most rows beyond, many joints at once
    D = terms.dq_dq(q, c)
    h = 1e-7
    num = np.stack([(terms.dq(q + h * e, c) - terms.dq(q - h * e, c)) / (2 * h)
                    for e in np.eye(6)], axis=2)
    np.testing.assert_allclose(D, num, atol=2e-9)
    # the joint Jacobian through the held corrections as well
    J = model.joint_jacobian(q[:20], outputs="position")
    num = np.stack([(model.positions(q[:20] + h * e) - model.positions(q[:20] - h * e))
                    / (2 * h) for e in np.eye(6)], axis=2)
    np.testing.assert_allclose(J, num, atol=1e-5)


def test_retraction_of_a_prismatic_joint_and_a_full_turn():
    env = JointEnvelope((0.0, -np.pi), (10.0, np.pi), (False, True))
    r = Retraction(env, np.array([[12.0, 4.0], [5.0, 1.0]]))
    np.testing.assert_array_equal(r.a[:, 0], [10.0, 5.0])
    np.testing.assert_array_equal(r.slope[:, 0], [0.0, 1.0])
    # periodic terms of a full-turn joint as they are; a scale term clipped
    v, d = r.one_joint(1, np.sin, np.cos, periodic=True)
    np.testing.assert_allclose(v, np.sin([4.0, 1.0]))
    v, d = r.one_joint(1, lambda x: x, np.ones_like, periodic=False)
    np.testing.assert_allclose(v, [np.pi, 1.0])
    np.testing.assert_allclose(d, [0.0, 1.0])


def test_envelope_in_the_model_file_round_trips(ur5, tmp_path):
    q = random_configurations(ur5, 50, np.random.default_rng(5)) * 0.5
    env = JointEnvelope.of(q, [True] * 6)
    model = with_terms(ur5, ["harmonic"], 1, env)
    path = tmp_path / "m.yaml"
    kinecal.save_model(model, path)
    back = kinecal.load_model(path)
    np.testing.assert_allclose(back.joint_errors.envelope.low, env.low, rtol=1e-14)
    np.testing.assert_allclose(back.joint_errors.envelope.high, env.high, rtol=1e-14)
    text = path.read_text().replace("envelope:", "envelope_x:")
    path.write_text(text)
    with pytest.raises(InputError, match="envelope_x"):
        kinecal.load_model(path)


def test_blocked_folds_and_partitions():
    values = np.array([5.0, 1.0, 3.0, 2.0, 4.0, 0.0])
    f = blocked_folds(values, 3)
    np.testing.assert_array_equal(f, [2, 0, 1, 1, 2, 0])  # contiguous in value order
    q = np.c_[values, np.zeros(6), values[::-1]]
    parts = partitions(q, 2)
    assert [p.name for p in parts] == ["random", "q1", "q3"]  # q2 never moves
    parts = partitions(q, 2, time=np.arange(6.0))
    assert [p.name for p in parts] == ["random", "time", "q1", "q3"]
    np.testing.assert_array_equal(parts[1].folds, [0, 0, 0, 1, 1, 1])
    within = [CVScore(1.0, 0.1, np.zeros(2)), CVScore(0.8, 0.1, np.zeros(2))]
    beyond = [[CVScore(2.0, 0.5, np.zeros(2)), CVScore(3.0, 0.5, np.zeros(2))],
              [CVScore(1.0, 0.5, np.zeros(2)), CVScore(1.0, 0.5, np.zeros(2))]]
    out = within_and_beyond(within, beyond)
    assert [s.mean for s in out] == [1.25, 1.4] and [s.se for s in out] == [0.1, 0.1]


@pytest.mark.parametrize("spec, values", [
    # harmonics of an order no candidate has, on q1 (the joint whose half is held out)
    (JointErrors(harmonics=5, harmonic_joints=(1, 2)), {"dq1.sin5": 3e-4, "dq2.cos1": 2e-4}),
    # and on q2, q3 over partial turns
    (JointErrors(harmonics=6, harmonic_joints=(2, 3)),
     {"dq2.sin6": 4e-4, "dq3.cos5": 3e-4, "dq2.cos1": 2e-4}),
])
def test_auto_over_half_of_q1_validated_on_the_other_half(ur5, spec, values):
    """Calibrated over q1 < 0, validated over q1 >= 0: auto within 2 % of the geometric
    calibration or better. (Without the held terms and the blocked folds, auto chose
    harmonic3 and harmonic2+scale here: 4.8 mm and 0.43 mm against geometric 0.12 and
    0.18 mm.)"""
    rng = np.random.default_rng(1)
    q = random_configurations(ur5, 600, rng)
    q[:, 0] = rng.uniform(-np.pi, np.pi, 600)
    cal_i, val_i = np.flatnonzero(q[:, 0] < 0)[:300], np.flatnonzero(q[:, 0] >= 0)[:300]
    model = dataclasses.replace(ur5, joint_errors=spec)
    e = np.zeros(model.n_params)
    e[:ur5.n_params] = simulate(ur5, 1, errors="random", rng=1).true_params - ur5.nominal
    for name, v in values.items():
        e[model.index([name])[0]] = v
    sim = simulate(model, 600, errors=e, noise=0.02, q=q, rng=1)
    cal, val = sim.data.subset(cal_i), sim.data.subset(val_i)
    geo = kinecal.calibrate(ur5, cal, validate=val)
    with kinecal.diagnostics.collect():  # validation beyond the range: warned, on purpose
        auto = kinecal.calibrate_error_model(ur5, cal, "auto", validate=val)
    assert auto.val_after.mean() <= 1.02 * geo.val_after.mean()
    assert any(d.code == "outside-calibrated-range" for d in auto.warnings)
    table = auto.extra["error_model"]["candidates"]
    assert set(table[0]["cv_blocked"]) == {f"q{j}" for j in range(1, 7)}


def test_parameter_tolerance_judges_a_joint_by_its_whole_correction(ur5):
    """Over a partial turn a joint's harmonics and scale cancel at tens of degrees each (the
    UR5 grid: dq1.sin2 -43.7 deg was reported as beyond the tolerances); the correction
    they make is what is judged. A real offset error still is."""
    cal = kinecal.read_measurements("ur5-laser-tracker:grid", ur5)
    with kinecal.diagnostics.collect() as found:
        res = kinecal.calibrate_error_model(ur5, cal, "harmonic+scale", harmonics=4)
    coef = res.nominal_model.index([n for n in res.free if n.startswith("dq")])
    assert np.degrees(np.abs(res.params[coef])).max() > 10.0  # cancelling coefficients
    assert not [d for d in found if d.code == "parameter-tolerance"]
    e = {"theta3": 4 * DEG}  # eight angle tolerances
    sim = simulate(ur5, 200, errors=e, noise=0.01, rng=21)
    with kinecal.diagnostics.collect() as found:
        kinecal.calibrate_error_model(ur5, sim.data, "harmonic", harmonics=1)
    msg = [d.message for d in found if d.code == "parameter-tolerance"]
    assert msg and "joint 3 offset and terms +4" in msg[0]
