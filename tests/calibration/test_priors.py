"""Priors on the free parameters (`kinecal.calibration.serial.prior`, docs/priors.md): the
rows, the MAP estimate against an independent ridge fit and on a known truth, the posterior
covariance in the directions only the prior decides, the choice of ``auto``, the stacked
kinds, and bad input."""

import dataclasses
import warnings

import numpy as np
import pytest
from scipy.optimize import least_squares

import kinecal
from kinecal.calibration.serial.prior import parse_prior, resolve_prior
from kinecal.calibration.serial.prior_fit import PriorProblem
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.calibration.serial.simulate import random_errors, simulate
from kinecal.errors import InputError


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kw)


@pytest.fixture(scope="module")
def small():
    """The IRB-120, 30 poses with 1 mm noise, true errors within the tolerances."""
    m = kinecal.load_model("irb120")
    return m, simulate(m, 30, noise=1.0, rng=11)


def test_prior_rows_and_their_jacobian(small):
    """The rows are ``noise (x - mu) / s`` after the data rows; the Jacobian matches
    central differences and the normal equations are those of the stacked rows."""
    m, sim = small
    names = list(m.calibratable)
    prob = CalibrationProblem(m, sim.data, names)
    spec = parse_prior(m, "lengths=0.5,angles=0.1,theta2=none")
    prior = resolve_prior(m, spec, names)
    k = m.index(["theta2"])[0]
    assert not np.isfinite(prior.sigma[names.index("theta2")])
    assert prior.sigma[names.index("d1")] == 0.5
    assert prior.sigma[names.index("alpha3")] == pytest.approx(np.radians(0.1))
    pp = PriorProblem(prob, prior, 0.7)
    x = prob.x0 + 0.001 * np.arange(len(names))
    r = pp.residuals(x)
    m_rows = 3 * len(sim.data)
    tail = np.where(np.isfinite(prior.sigma), 0.7 * (x - prior.mean) / prior.sigma, 0.0)
    np.testing.assert_allclose(r[m_rows:], tail, rtol=1e-12, atol=1e-15)
    J = pp.jacobian(x)
    h = 1e-6
    num = np.column_stack([(pp.residuals(x + h * e) - pp.residuals(x - h * e)) / (2 * h)
                           for e in np.eye(len(names))])
    np.testing.assert_allclose(J, num, atol=1e-5 * np.abs(num).max())
    r2, A, g = pp.normal_equations(x)
    np.testing.assert_allclose(r2, r, rtol=1e-12)
    np.testing.assert_allclose(A, J.T @ J, rtol=1e-9, atol=1e-9 * np.abs(A).max())
    np.testing.assert_allclose(g, J.T @ r, rtol=1e-9, atol=1e-9 * np.abs(g).max())
    assert k == m.index(["theta2"])[0]


def test_map_equals_an_independent_ridge_fit(small):
    """kinecal's MAP fit minimises the data rows plus ridge rows built here (the same noise
    and sigmas): its cost is not above scipy least_squares' and scipy does not move from
    it."""
    m, sim = small
    res = _quiet(kinecal.calibrate, m, sim.data, free="all", prior="lengths=0.3,angles=0.2",
                 sigma=1.0)
    names = list(m.calibratable)
    idx = m.index(names)
    s = np.where(m.is_angle()[idx], np.radians(0.2), 0.3)
    q, xyz = sim.data.q, sim.data.xyz

    def rows(x):
        p = m.nominal
        p[idx] = x
        return np.concatenate([(m.positions(q, p) - xyz).ravel(),
                               1.0 * (x - m.nominal[idx]) / s])

    peer = least_squares(rows, m.nominal[idx], xtol=1e-15, ftol=1e-15, gtol=1e-15,
                         x_scale="jac")
    mine = 0.5 * float(np.sum(rows(res.params[idx]) ** 2))
    assert mine <= peer.cost * (1 + 1e-12)  # scipy's 2-point fit stops in flat directions
    # kinecal's answer is a minimum of the peer's cost: scipy does not move from it
    again = least_squares(rows, res.params[idx], xtol=1e-15, ftol=1e-15, gtol=1e-15,
                          x_scale="jac")
    np.testing.assert_allclose(again.x, res.params[idx], atol=1e-7)
    assert res.extra["prior"]["noise_source"] == "stated"


def test_map_recovers_a_known_truth_where_the_data_are_blind():
    """Noise-free data of a known truth and a prior centred on it (a CSV with means):
    the MAP fit recovers every parameter, also those the poses cannot identify (which a
    fit without a prior leaves arbitrary)."""
    m = kinecal.load_model("irb120")
    err = random_errors(m, np.random.default_rng(4))
    sim = simulate(m, 40, errors=err, noise=0.0, rng=5)
    truth = m.nominal + err
    conv = np.where(m.is_angle(), 180.0 / np.pi, 1.0)
    names = list(m.calibratable)
    spec = {n: (0.5, truth[m.index([n])[0]] * conv[m.index([n])[0]]) for n in names}
    res = _quiet(kinecal.calibrate, m, sim.data, free="all", prior=spec, sigma=0.01)
    idx = m.index(names)
    np.testing.assert_allclose(res.params[idx], truth[idx], atol=1e-8)
    plain = _quiet(kinecal.calibrate, m, sim.data, free="all")
    null = len(names) - plain.identifiability.rank  # directions the poses cannot see
    blind = m.index(plain.unidentifiable_free())
    assert null >= 1 and np.abs(plain.params[blind] - truth[blind]).max() > 1e-3
    assert res.extra["prior"]["directions"]["prior"] >= null
    assert np.isfinite(res.std[idx]).all()


def test_covariance_in_a_prior_decided_direction_is_the_priors():
    """theta1 and the base frame's rz turn the UR5 about the same axis: the data see their
    sum, never their difference. Its posterior variance is the prior's exactly (not zero,
    not unbounded), the sum's far smaller; the split counts the direction as the prior's."""
    m = kinecal.load_model("ur5")
    sim = simulate(m, 40, noise=0.05, rng=2)
    s_deg = 0.5
    res = _quiet(kinecal.calibrate, m, sim.data, free="all",
                 prior={"lengths": 1.0, "angles": s_deg, "base.*": s_deg, "tool.*": 1.0})
    i, j = res.free.index("theta1"), res.free.index("base.rz")
    C = res.covariance
    diff = (C[i, i] + C[j, j] - 2 * C[i, j]) / 2.0
    total = (C[i, i] + C[j, j] + 2 * C[i, j]) / 2.0
    # (exactly the prior's but for the fitted base tilt of ~1e-3 rad between the two axes)
    assert diff == pytest.approx(np.radians(s_deg) ** 2, rel=1e-4)
    assert total < 1e-3 * diff
    assert res.extra["prior"]["directions"]["prior"] >= 1
    assert {"theta1", "base.rz"} <= set(res.extra["prior"]["decided_by_prior"]) or \
        res.extra["prior"]["data_share"]["theta1"] < 0.75


def test_auto_keeps_no_prior_on_a_large_set():
    """2000 poses decide everything: auto takes no prior, and the result is the plain
    fit's, bit for bit."""
    m = kinecal.load_model("irb120")
    sim = simulate(m, 2000, noise=0.05, rng=3)
    plain = _quiet(kinecal.calibrate, m, sim.data)
    auto = _quiet(kinecal.calibrate, m, sim.data, prior="auto")
    assert auto.extra["prior"]["used"] == "none"
    assert plain.extra["prior"] is None
    np.testing.assert_array_equal(auto.params, plain.params)
    np.testing.assert_array_equal(auto.std, plain.std)


def test_auto_takes_a_prior_on_a_small_set_and_it_pays(small):
    """30 poses for 25 free parameters: auto's prior lowers the error on the true arm
    over the workspace (held-out), against the plain fit."""
    m, sim = small
    q = kinecal.calibration.serial.simulate.random_configurations(
        m, 400, np.random.default_rng(9))
    truth = m.positions(q, sim.true_params)
    plain = _quiet(kinecal.calibrate, m, sim.data, free="all")
    auto = _quiet(kinecal.calibrate, m, sim.data, free="all", prior="auto")
    entry = auto.extra["prior"]
    assert entry["used"] != "none" and entry["strength"] in [
        c["strength"] for c in entry["cross_validation"]["candidates"]]
    e_plain = np.linalg.norm(m.positions(q, plain.params) - truth, axis=1).mean()
    e_auto = np.linalg.norm(m.positions(q, auto.params) - truth, axis=1).mean()
    assert e_auto < 0.9 * e_plain


def test_prior_from_a_previous_result(small, tmp_path):
    """--prior-from centres the prior on the previous result's values."""
    m, sim = small
    first = _quiet(kinecal.calibrate, m, sim.data)
    first.to_json(tmp_path / "first.json")
    again = _quiet(kinecal.calibrate, m, simulate(m, 30, errors=sim.true_params - m.nominal,
                                                   noise=1.0, rng=12).data,
                   prior="lengths=1e-6,angles=1e-6", prior_from=tmp_path / "first.json")
    idx = m.index(again.free)
    np.testing.assert_allclose(again.params[idx], first.params[idx], atol=1e-5)
    assert again.extra["prior"]["mean"] == str(tmp_path / "first.json")


def test_stacked_kinds_take_the_prior_as_rows():
    """Planes cannot see the base frame: with the prior it is free and its standard error
    is the prior's, the plane offsets taking up the rest."""
    from kinecal.calibration.blocks.simulate import simulate_kind

    m = kinecal.load_model("ur5")
    sim = simulate_kind(m, "plane", 30, true_params=m.nominal + random_errors(
        m, np.random.default_rng(1), [n for n in m.calibratable if not n.startswith("base")]),
        noise=0.05, rng=1, groups=3)
    res = _quiet(kinecal.calibrate, m, [sim.data], free="all",
                 prior={"lengths": 1.0, "angles": 0.5, "base.*": 2.0, "tool.*": 1.0})
    k = m.index(["base.x"])[0]
    assert "base.x" in res.free
    assert res.std[k] == pytest.approx(2.0, rel=1e-6)
    assert "base.x" in res.extra["prior"]["decided_by_prior"]
    plain = _quiet(kinecal.calibrate, m, [sim.data])
    assert "base.x" not in plain.free


@pytest.mark.parametrize("prior, match", [
    ("lenghts=0.5", "unknown group 'lenghts'"),
    ("lengths=-0.5", "positive"),
    ("lengths=abc", "1-sigma"),
    ("lengths", "GROUP=SIGMA"),
    ({"theta9": 0.1}, "unknown group 'theta9'"),
])
def test_bad_prior_is_refused(small, prior, match):
    m, sim = small
    with pytest.raises(InputError, match=match) as err:
        kinecal.calibrate(m, sim.data, prior=prior)
    assert err.value.option == "--prior"


def test_prior_needs_least_squares(small):
    m, sim = small
    with pytest.raises(InputError, match="--method lm"):
        kinecal.calibrate(m, sim.data, method="pso", prior="auto")
    with pytest.raises(InputError, match="--loss linear"):
        kinecal.calibrate(m, sim.data, loss="soft_l1", prior="auto")


@pytest.mark.parametrize("text, row, match", [
    ("name,sigma\nd1,0.5\ntheta9,0.1\n", 2, "unknown parameter 'theta9'"),
    ("name,sigma\nd1,-0.5\n", 1, "positive"),
    ("name,sigma,mean\nd1,0.5,x\n", 1, "mean: expected a number"),
    ("name,sigma\nd1,0.5\nd1,0.2\n", 2, "given twice"),
    ("name,value\nd1,0.5\n", None, "header"),
])
def test_bad_prior_file_is_refused_with_its_row(small, tmp_path, text, row, match):
    m, sim = small
    path = tmp_path / "prior.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=match) as err:
        kinecal.calibrate(m, sim.data, prior=path)
    assert err.value.file == str(path) and err.value.row == row


def test_prior_file_with_none_and_means(small, tmp_path):
    """A file's ``none`` leaves a parameter without prior; its mean moves the prior."""
    m, sim = small
    path = tmp_path / "prior.csv"
    path.write_text("name,sigma,mean\nd1,1e-6,291.5\na2,none,\n")
    res = _quiet(kinecal.calibrate, m, dataclasses.replace(sim.data), prior=path)
    assert res.params[m.index(["d1"])[0]] == pytest.approx(291.5, abs=1e-4)
    assert set(res.extra["prior"]["sigma"]) == {"d1"}
