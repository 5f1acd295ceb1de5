"""Serial-arm calibration: identifiability, exact recovery, noise, real UR5 data, results."""

import json

import numpy as np
import pytest

import kinecal
from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.problem import CalibrationProblem, resolve_free
from kinecal.calibration.serial.simulate import read_truth, simulate, write_truth
from kinecal.cli import main
from kinecal.data import Measurements
from kinecal.errors import InputError


@pytest.fixture(scope="module")
def scanner():
    from importlib import resources

    m = kinecal.load_model("hu2005-scanner")
    path = resources.files("kinecal") / "robots" / "hu2005-scanner.truth.json"
    return m, read_truth(str(path), m)


def test_identifiability_irb120_rank_20_of_25(capsys):
    assert main(["identifiability", "irb120", "--poses", "50", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["rank"] == 20 and rep["n_parameters"] == 25
    assert len(rep["identifiable"]) == 20 and len(rep["unidentifiable"]) == 5
    # theta6 and alpha6 cannot move a point on the last axis: always unidentifiable
    assert {"theta6", "alpha6"} <= set(rep["unidentifiable"])
    assert set(rep["observability"]) == {"O1", "O2", "O3", "O4", "O5"}


def test_identifiability_scanner_23_of_25_last_link(capsys):
    assert main(["identifiability", "hu2005-scanner", "--poses", "50", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["rank"] == 23 and rep["n_parameters"] == 25
    last_link = {"theta6", "d6", "a6", "alpha6"}
    assert set(rep["unidentifiable"]) <= last_link
    for combo in rep["confounded_with"].values():
        assert set(combo) <= last_link and len(combo) == 1  # confounded pairwise, last link
        # 1 rad of theta6 or alpha6 acts like 100 mm (the probe length) of a6 or d6
        assert abs(abs(next(iter(combo.values()))) - 100.0) < 1e-6


def test_noise_free_scanner_reaches_round_off(scanner):
    m, truth = scanner
    cal = simulate(m, 50, errors=truth - m.nominal, rng=1)
    val = simulate(m, 100, errors=truth - m.nominal, rng=2)
    res = calibrate(m, cal.data, validate=val.data)
    assert res.calibration_stats["after"]["mean"] <= 1e-9
    assert res.validation_stats["after"]["mean"] <= 1e-9
    assert res.calibration_stats["before"]["mean"] > 1.0
    assert res.identifiability.rank == 23


@pytest.mark.parametrize("seed", [0, 1])
def test_noise_free_irb120_random_errors(seed):
    m = kinecal.load_model("irb120")
    cal = simulate(m, 50, errors="random", rng=seed)
    val = simulate(m, 100, errors=cal.true_params - m.nominal, rng=seed + 10)
    res = calibrate(m, cal.data, validate=val.data)
    assert res.calibration_stats["after"]["mean"] <= 1e-9
    assert res.validation_stats["after"]["mean"] <= 1e-9


@pytest.mark.parametrize("name", ["hu2005-scanner", "irb120"])
def test_errors_in_identifiable_parameters_are_recovered(name):
    m = kinecal.load_model(name)
    rng = np.random.default_rng(7)
    cal0 = simulate(m, 50, errors="zero", rng=3)
    ident, _ = resolve_free(m, cal0.data, "identifiable")
    errors = np.zeros(m.n_params)
    idx = m.index(ident)
    half = np.where(m.is_angle()[idx], m.tolerances["angle"], m.tolerances["length"])
    errors[idx] = rng.uniform(-half, half) * 0.5
    cal = simulate(m, 50, errors=errors, q=cal0.data.q)
    res = calibrate(m, cal.data, free=ident)
    np.testing.assert_allclose(res.params, cal.true_params, rtol=0, atol=1e-9)


def test_noisy_validation_near_noise_floor():
    m = kinecal.load_model("irb120")
    ratios = []
    for seed in range(3):
        cal = simulate(m, 50, errors="random", noise=0.02, rng=seed)
        e = cal.true_params - m.nominal
        val = simulate(m, 100, errors=e, noise=0.02, rng=100 + seed)
        res = calibrate(m, cal.data, validate=val.data)
        floor = np.linalg.norm(val.exact_xyz - val.data.xyz, axis=1).mean()
        ratios.append(res.validation_stats["after"]["mean"] / floor)
    assert max(ratios) <= 1.25, ratios


def test_standard_errors_cover_the_truth():
    """95 % intervals cover the truth in about 95 % of runs (small Monte Carlo here;
    the 200-run study is in benchmarks)."""
    m = kinecal.load_model("irb120")
    q = simulate(m, 50, errors="zero", rng=0).data.q
    ident, _ = resolve_free(m, Measurements(q, m.positions(q)), "identifiable")
    idx = m.index(ident)
    rng = np.random.default_rng(11)
    hits, total = 0, 0
    for _ in range(40):
        e = np.zeros(m.n_params)
        half = np.where(m.is_angle()[idx], 0.002, 0.1)
        e[idx] = rng.uniform(-half, half)
        sim = simulate(m, 0, errors=e, noise=0.02, rng=rng, q=q)
        res = calibrate(m, sim.data, free=ident)
        z = np.abs(res.params[idx] - sim.true_params[idx]) / res.std[idx]
        hits += int((z <= 1.96).sum())
        total += z.size
    coverage = hits / total
    assert 0.88 <= coverage <= 0.99, coverage


def test_real_ur5_laser_tracker():
    m = kinecal.load_model("ur5")
    grid = kinecal.read_measurements("ur5-laser-tracker:grid", m)
    test = kinecal.read_measurements("ur5-laser-tracker:random", m)
    res = calibrate(m, grid, validate=test)
    assert res.validation_stats["before"]["mean"] == pytest.approx(2.5647, abs=1e-3)
    assert res.validation_stats["after"]["mean"] <= 0.12
    assert {"base.x", "base.y", "tool.y"} <= set(res.free)


def test_householder_on_all_scanner_parameters_reports_singularity(scanner):
    m, truth = scanner
    cal = simulate(m, 50, errors=truth - m.nominal, rng=1)
    res = calibrate(m, cal.data, "householder", free="all", maxiter=10)
    assert "singular" in res.message
    assert len(res.free) == 25
    frozen = res.to_dict()["singular_parameters"]
    assert len(frozen) == 2 and set(frozen) <= {"theta6", "d6", "a6", "alpha6"}


def test_robust_loss_flags_outliers():
    m = kinecal.load_model("irb120")
    cal = simulate(m, 60, errors="random", noise=0.02, rng=5)
    xyz = cal.data.xyz.copy()
    xyz[[7, 31]] += [5.0, -4.0, 3.0]
    bad = Measurements(cal.data.q, xyz)
    val = simulate(m, 100, errors=cal.true_params - m.nominal, noise=0.02, rng=6)
    plain = calibrate(m, bad, validate=val.data)
    robust = calibrate(m, bad, validate=val.data, loss="soft_l1")
    assert robust.outliers == [7, 31]
    assert robust.validation_stats["after"]["mean"] < 0.5 * plain.validation_stats["after"]["mean"]


def test_problem_jacobian_with_weights_matches_finite_differences():
    m = kinecal.load_model("kr6-craig")
    sim = simulate(m, 10, errors="random", rng=2)
    w = np.linspace(0.5, 2.0, 10)
    data = Measurements(sim.data.q, sim.data.xyz, w)
    pr = CalibrationProblem(m, data, list(m.calibratable))
    x = pr.x0 + 0.001
    J = pr.jacobian(x)
    h = 1e-6
    Jn = np.column_stack([(pr.residuals(x + h * e) - pr.residuals(x - h * e)) / (2 * h)
                          for e in np.eye(pr.n_free)])
    assert np.abs(J - Jn).max() <= 1e-6 * np.abs(Jn).max()


def test_too_few_poses_is_an_input_error():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 5, errors="zero", rng=0)
    with pytest.raises(InputError, match="poses"):
        calibrate(m, sim.data, free="all")


def test_metaheuristic_same_seed_same_result():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 20, errors="random", rng=0)
    a = calibrate(m, sim.data, "pso", rng=3, maxiter=5)
    b = calibrate(m, sim.data, "pso", rng=3, maxiter=5)
    np.testing.assert_array_equal(a.params, b.params)
    assert a.history == b.history and len(a.history) == 6


def test_cli_simulate_calibrate_round_trip(tmp_path, capsys):
    data, truth = tmp_path / "d.csv", tmp_path / "t.json"
    val = tmp_path / "v.csv"
    assert main(["simulate", "irb120", "--poses", "40", "--seed", "3", "--out", str(data),
                 "--truth-out", str(truth)]) == 0
    assert main(["simulate", "irb120", "--poses", "30", "--seed", "4", "--errors", str(truth),
                 "--out", str(val)]) == 0
    out, model_out = tmp_path / "r.json", tmp_path / "cal.yaml"
    assert main(["calibrate", "irb120", str(data), "--validate", str(val), "--out", str(out),
                 "--model-out", str(model_out), "--quiet"]) == 0
    res = json.loads(out.read_text())
    for key in ("kinecal", "model", "method", "seed", "parameters", "unidentifiable", "rank",
                "condition_number", "calibration", "validation", "improvement_percent",
                "iterations", "evaluations", "seconds", "history"):
        assert key in res
    assert res["validation"]["after"]["mean"] < 1e-9
    assert set(res["parameters"]["d1"]) == {"nominal", "identified", "std", "free"}
    capsys.readouterr()
    # the calibrated model file reproduces the truth's positions
    m_cal = kinecal.load_model(model_out)
    m = kinecal.load_model("irb120")
    v = kinecal.read_measurements(val, m)
    assert np.linalg.norm(m_cal.positions(v.q) - v.xyz, axis=1).max() < 1e-8
    # fk with --params reads the result back
    assert main(["fk", "irb120", str(val), "--params", str(out)]) == 0
    fk = np.loadtxt(capsys.readouterr().out.splitlines(), delimiter=",", skiprows=1)
    assert np.abs(fk - v.xyz).max() < 1e-6


def test_truth_file_round_trip(tmp_path):
    m = kinecal.load_model("ur5")
    sim = simulate(m, 3, errors="random", rng=9)
    write_truth(tmp_path / "t.json", m, sim.true_params)
    np.testing.assert_allclose(read_truth(tmp_path / "t.json", m), sim.true_params, atol=1e-12)


def test_predicted_position_error_matches_monte_carlo():
    """sqrt(trace(J C J^T)) predicts the model's RMS error against the truth (200-run
    check: ratio 0.93-1.08 per pose, mean 1.002; 60 runs here)."""
    m = kinecal.load_model("irb120")
    q = simulate(m, 40, errors="zero", rng=0).data.q
    qv = simulate(m, 30, errors="zero", rng=1).data.q
    ident, _ = resolve_free(m, Measurements(q, m.positions(q)), "identifiable")
    idx = m.index(ident)
    e = np.zeros(m.n_params)
    e[idx] = np.random.default_rng(3).uniform(-1, 1, idx.size) * np.where(
        m.is_angle()[idx], 0.002, 0.1)
    exact = m.positions(qv, m.nominal + e)
    rng = np.random.default_rng(5)
    errors, predicted = [], []
    for _ in range(60):
        sim = simulate(m, 0, errors=e, noise=0.02, q=q, rng=rng)
        res = calibrate(m, sim.data, free=ident)
        errors.append(np.linalg.norm(m.positions(qv, res.params) - exact, axis=1))
        predicted.append(res.predicted_position_error(qv))
    ratio = np.sqrt((np.array(errors) ** 2).mean(axis=0)) / np.mean(predicted, axis=0)
    assert 0.9 <= ratio.mean() <= 1.1, ratio.mean()
    assert 0.7 <= ratio.min() and ratio.max() <= 1.4, ratio
    summary = res.to_dict()["predicted_error"]
    assert summary["calibration_mean"] > 0 and summary["validation_mean"] is None


def test_writing_a_result_costs_no_memory_per_pose():
    """The predicted error of the result (`to_dict`) is computed in blocks of poses: its
    peak memory does not grow with the poses (it took 1.58 kB per pose: the Jacobian of
    every pose at once), and its value is the plain formula's."""
    import tracemalloc

    m = kinecal.load_model("ur5")
    sim = simulate(m, 20000, noise=0.01, rng=4)
    res = calibrate(m, sim.data)
    peaks = {}
    for n in (8000, 20000):
        q = sim.data.q[:n]
        tracemalloc.start()
        pred = res.predicted_position_error(q)
        peaks[n] = tracemalloc.get_traced_memory()[1] - pred.nbytes
        tracemalloc.stop()
    assert (peaks[20000] - peaks[8000]) / 12000 < 100, peaks  # bytes per pose
    idx = m.index(res.free)
    J = m.identification_jacobian(sim.data.q[:50], res.params)[:, :, idx]
    plain = np.sqrt(np.trace(J @ res.covariance @ np.swapaxes(J, 1, 2), axis1=1, axis2=2))
    np.testing.assert_allclose(res.predicted_position_error(sim.data.q[:50]), plain,
                               rtol=1e-12)
