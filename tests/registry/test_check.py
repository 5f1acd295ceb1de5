"""The check's statistics: exact distribution functions, the whitened tests' size on an
unchanged robot (synthetic and simulated calibrations), the power and the estimate of a
joint-offset change, a ballbar check (its pivot fitted today), the base registered again,
and the limit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kinecal.registry.check_stats import chi2_sf, f_sf, judge


def test_distribution_functions_match_scipy():
    from scipy.special import chdtrc, fdtrc

    for k in (1, 2, 3, 7, 30, 97, 400):
        for x in np.geomspace(1e-3, 3000, 40):
            want = chdtrc(k, x)
            if want > 1e-290:
                assert chi2_sf(x, k) == pytest.approx(want, rel=1e-11)
    for d1 in (1, 4, 30):
        for d2 in (2, 9, 97, 1000):
            for x in np.geomspace(1e-3, 500, 40):
                want = fdtrc(d1, d2, x)
                if want > 1e-290:
                    assert f_sf(x, d1, d2) == pytest.approx(want, rel=1e-10)


def test_whitened_tests_hold_their_size_on_linear_gaussian_data():
    """r = e + A d with d ~ N(0, C): each test rejects alpha of the time, and a change along
    a direction is estimated without bias within its standard error."""
    rng = np.random.default_rng(1)
    m, k, q = 30, 12, 5
    A = rng.normal(size=(m, k)) * 40
    B = rng.normal(size=(k, k))
    C = B @ B.T * 1e-7
    D = rng.normal(size=(m, q)) * 30
    N = rng.normal(size=(m, 2))  # two unknowns fitted today
    obs = np.repeat(np.arange(10), 3)
    p, dp = [], []
    for _ in range(4000):
        r = rng.normal(0, 0.03, m) + A @ rng.multivariate_normal(np.zeros(k), C) \
            + N @ rng.normal(0, 5, 2)
        j = judge(r, np.full(m, 0.03), A, C, N, D, obs, 10, 0.01)
        p.append(j.p_value)
        dp.append(j.directed_p_value)
        assert j.dof == m - 2 and j.directed_dof == q
    p, dp = np.array(p), np.array(dp)
    for level in (0.01, 0.05, 0.2):
        assert abs((p < level).mean() - level) < 4 * np.sqrt(level / 4000) + 0.003
        assert abs((dp < level).mean() - level) < 4 * np.sqrt(level / 4000) + 0.003
    delta = np.array([0.002, 0, 0, 0, 0])
    z = []
    for _ in range(300):
        r = rng.normal(0, 0.03, m) + A @ rng.multivariate_normal(np.zeros(k), C) + D @ delta
        j = judge(r, np.full(m, 0.03), A, C, np.zeros((m, 0)), D, obs, 10, 0.01)
        z.append((j.change[0] - delta[0]) / j.change_std[0])
    assert abs(np.mean(z)) < 0.25 and 0.8 < np.std(z) < 1.2


def _cal(model, truth_errors, seed, poses=30, noise=0.03):
    import kinecal
    from kinecal.calibration.serial.simulate import simulate
    from kinecal.registry.check import calibrated_from_result

    sim = simulate(model, poses, errors=truth_errors, noise=noise, rng=seed)
    res = kinecal.calibrate(model, sim.data)
    return sim.true_params, calibrated_from_result(model, json.loads(json.dumps(
        res.to_dict())), "result.json")


def test_unchanged_robots_pass_at_the_stated_rate():
    """40 simulated UR5 calibrations (full-size errors on every parameter), 3 checks each
    of the unchanged arm at random poses: the overall F test (noise estimated by the
    calibration) rejects about alpha of them."""
    import kinecal
    from kinecal.calibration.serial.simulate import random_configurations
    from kinecal.data import Measurements
    from kinecal.registry.check import run_check

    m = kinecal.load_model("ur5")
    p, dp = [], []
    for c in range(40):
        truth, cal = _cal(m, "random", c)
        for k in range(3):
            q = random_configurations(m, 10, np.random.default_rng([c, k]))
            y = m.positions(q, truth) + np.random.default_rng([c, k, 1]).normal(0, 0.03,
                                                                                (10, 3))
            res = run_check(cal, [Measurements(q, y)], limit=0.2, alpha=0.05)
            assert res.noise_dof == 90 - cal.data["rank"]
            p.append(res.p_value)
            dp.append(res.directed["p_value"])
    p, dp = np.array(p), np.array(dp)
    assert (p < 0.05).mean() < 0.12 and (dp < 0.05).mean() < 0.12
    assert 0.35 < p.mean() < 0.65 and 0.35 < dp.mean() < 0.65


def test_a_joint_offset_change_is_found_and_measured(arm):
    from kinecal.io.kinds import read_kind
    from kinecal.registry.check import calibrated_from_result, run_check

    data = json.loads(arm.result.read_text())
    cal = calibrated_from_result(arm.model, data, arm.result)
    for value, verdict in ((0.0, "valid"), (0.03, "drifted"), (0.3, "recalibrate")):
        path = arm.measure(f"off-{value}.csv", arm.shifted("theta3", np.radians(value)),
                           seed=int(value * 1000))
        res = run_check(cal, [read_kind(path, arm.model)], limit=1.0)
        assert res.verdict == verdict
        if value:
            d = res.directions["theta3"]
            assert abs(d["change"] - value) < 4 * d["std"]
            others = [abs(v["change"]) / v["std"] for n, v in res.directions.items()
                      if n != "theta3"]
            assert max(others) < 5  # the change is put on its joint, not spread


def test_a_ballbar_check_fits_its_pivot_today(arm, tmp_path):
    """A check of another kind than the calibration's: a ballbar from an unknown pivot
    (fitted today). Unchanged: valid; a joint offset changed: found."""
    from kinecal.calibration.blocks.simulate import simulate_kind
    from kinecal.registry.check import calibrated_from_result, run_check

    cal = calibrated_from_result(arm.model, json.loads(arm.result.read_text()), arm.result)
    for change, verdicts in ((0.0, {"valid"}), (0.2, {"recalibrate", "drifted"})):
        p = arm.shifted("theta2", np.radians(change))
        data = simulate_kind(arm.model, "ballbar", 12, true_params=p, noise=0.005,
                             rng=np.random.default_rng(4), groups=1).data
        res = run_check(cal, [data], sigma=[0.005], limit=0.1)
        assert res.verdict in verdicts, (change, res.verdict, res.p_value)
        assert res.dof == 12 - 3  # the pivot's three coordinates fitted
        assert res.poses[0]["kind"] == "ballbar"


def test_the_base_registered_again_ignores_a_moved_instrument(arm):
    """The tracker set up elsewhere: without --register base the check sees a base change
    (recalibrate), with it the arm itself is judged (valid)."""
    from kinecal.io.kinds import read_kind
    from kinecal.registry.check import calibrated_from_result, run_check

    cal = calibrated_from_result(arm.model, json.loads(arm.result.read_text()), arm.result)
    p = arm.shifted("base.x", 2.0)
    p[arm.model.index(["base.rz"])[0]] += np.radians(0.5)
    path = arm.measure("moved-tracker.csv", p, seed=12)
    data = [read_kind(path, arm.model)]
    from kinecal import diagnostics

    with diagnostics.collect() as found:
        assert run_check(cal, data, limit=0.5).verdict == "recalibrate"
    assert [d.code for d in found] == ["check-base-moved"]
    res = run_check(cal, data, limit=0.5, register_base=True)
    assert res.verdict == "valid" and res.dof == 30 - 6 and res.directions == {}


def test_the_default_limit_is_twice_the_calibration_s_error(arm):
    from kinecal.io.kinds import read_kind
    from kinecal.registry.check import LIMIT_FACTOR, calibrated_from_result, run_check

    data = json.loads(arm.result.read_text())
    cal = calibrated_from_result(arm.model, data, arm.result)
    res = run_check(cal, [read_kind(arm.measure("lim.csv", seed=3), arm.model)])
    assert res.limit == pytest.approx(LIMIT_FACTOR * data["calibration"]["after"]["rms"])


def test_a_moved_instrument_is_named(arm):
    """A change that is a rigid move of the base: check-base-moved says so, and says what
    to do; a joint's slip does not raise it."""
    from kinecal import diagnostics
    from kinecal.io.kinds import read_kind
    from kinecal.registry.check import calibrated_from_result, run_check

    cal = calibrated_from_result(arm.model, json.loads(arm.result.read_text()), arm.result)
    moved = arm.shifted("base.y", 1.5)
    slip = arm.shifted("theta2", np.radians(0.2))
    for params, raised in ((moved, True), (slip, False)):
        path = arm.measure("frame.csv", params, seed=21)
        with diagnostics.collect() as found:
            run_check(cal, [read_kind(path, arm.model)], limit=0.5)
        codes = [d.code for d in found]
        assert ("check-base-moved" in codes) == raised, codes
        if raised:
            assert "--register base" in found[0].message and "1.5" in found[0].message


def test_a_calibration_without_its_base_registers_today_s_frame(tmp_path, cli, monkeypatch):
    """Two tracker stations (each its own frame: the calibration does not determine the
    arm's base): a check of tracker points fits today's frame itself and says so; without
    that, the unknown frame would read as a robot that moved."""
    monkeypatch.chdir(tmp_path)
    for seed, name in ((21, "s1.csv"), (22, "s2.csv")):
        extra = ["--truth-out", "truth.json"] if seed == 21 else ["--errors", "truth.json"]
        assert cli("simulate", "ur5", "--poses", "30", "--noise", "0.02", "--seed", seed,
                   "--out", name, *extra)[0] == 0
    code, _, err = cli("calibrate", "ur5", "s1.csv", "s2.csv", "--station-per-file",
                       "--register", "ST-1", "--quiet")
    assert code == 0, err
    assert cli("plan-check", "ur5", "--out", "poses.csv")[0] == 0
    assert cli("simulate", "ur5", "--joints", "poses.csv", "--errors", "truth.json",
               "--noise", "0.02", "--seed", "23", "--out", "today.csv")[0] == 0
    code, out, err = cli("check", "ST-1", "today.csv", "--limit", "0.3", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["verdict"] == "valid" and doc["register_base"]
    assert doc["base_registered"] == "the calibration did not determine the base frame"
    assert doc["dof"] == 30 - 6


def test_one_process_checking_in_two_registries_judges_each_robot_by_its_own(tmp_path, arm):
    """Record ids repeat from one registry to another: a process (a Dask worker, a script)
    that checks robots of two registries must judge each by its own calibration (the
    kept calibrations were once keyed by id: the second robot was judged by the first's)."""
    import kinecal
    from kinecal.calibration.serial.simulate import simulate
    from kinecal.data import Measurements
    from kinecal.registry.fleet import check_robot
    from kinecal.registry.records import calibration_row, model_source
    from kinecal.registry.store import open_registry

    other = simulate(arm.model, 40, errors="random", noise=0.03, rng=99)
    doc_b = json.loads(json.dumps(kinecal.calibrate(arm.model, other.data).to_dict()))
    verdicts = []
    for name, doc, truth in (("a.db", json.loads(arm.result.read_text()), arm.truth),
                             ("b.db", doc_b, other.true_params)):
        with open_registry(str(tmp_path / name)) as reg:
            reg.add_event("X", calibration_row("X", doc, name, source=model_source(None, doc)),
                          current="arm")
            y = arm.model.positions(arm.q, truth) + np.random.default_rng(1).normal(
                0, 0.03, (len(arm.q), 3))
            _, stored, _ = check_robot(reg, "X", [Measurements(arm.q, y)], limit=0.3)
            verdicts.append((stored["calibration_id"], stored["verdict"]))
    assert verdicts == [(1, "valid"), (1, "valid")]
