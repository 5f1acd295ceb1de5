"""The residual-block framework: every kind's analytic Jacobian (arm and its own unknowns)
against central differences, the stacked normal equations against the dense Jacobian,
the start values of each kind's unknowns, and the nuisance marginalisation."""

import numpy as np
import pytest

import kinecal
from kinecal.calibration.blocks.analysis import analyse_stack
from kinecal.calibration.blocks.ballbar import BallbarBlock, sphere_fit
from kinecal.calibration.blocks.pair import PairBlock
from kinecal.calibration.blocks.plane import PlaneBlock, plane_fit
from kinecal.calibration.blocks.point import PointBlock
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.tracker import TrackerBlock
from kinecal.calibration.blocks.uncertainty import marginal_normal
from kinecal.calibration.serial.simulate import random_configurations, random_errors
from kinecal.data import GaugeMeasurements, Measurements
from kinecal.spatial import matrix_from_axis_angle


@pytest.fixture(scope="module")
def arm():
    m = kinecal.load_model("irb120")
    gen = np.random.default_rng(0)
    p = m.nominal + random_errors(m, gen)
    return m, p, gen


def _gauge(kind, q, groups, distance=None):
    names = tuple(f"g{i}" for i in range(groups.max() + 1))
    return GaugeMeasurements(kind, q, groups, names, distance)


def _blocks(m, gen):
    q = random_configurations(m, 24, gen)
    g = np.repeat(np.arange(3), 8)
    P = m.positions(q)
    bb = BallbarBlock(_gauge("ballbar", q, g, 200.0 + gen.uniform(0, 50, 24)))
    pair = PairBlock(_gauge("pair", q, np.repeat(np.arange(12), 2),
                            np.repeat(gen.uniform(100, 300, 12), 2)))
    pt = PointBlock(_gauge("point", q, g))
    pl = PlaneBlock(_gauge("plane", q, g))
    R = matrix_from_axis_angle(gen.normal(0, 0.1, (24, 3))) @ m.fk(q)[:, :3, :3]
    tr = TrackerBlock(Measurements(q, P + gen.normal(0, 1.0, P.shape), rotations=R))
    return [bb, pair, pt, pl, tr]


def test_every_kind_jacobian_matches_central_differences(arm):
    m, p, gen = arm
    cols = m.index(list(m.calibratable))
    for b in _blocks(m, gen):
        v = b.start(m, m.nominal) + gen.normal(0, 0.05, b.n_nuisance)
        rows = b.evaluate(m, p, v, cols, jacobian=True)
        assert rows.r.shape == (b.n_rows,) and rows.arm.shape == (b.n_rows, cols.size)
        h = 1e-6
        num = np.empty_like(rows.arm)
        for j, c in enumerate(cols):
            dp = np.zeros(m.n_params)
            dp[c] = h
            num[:, j] = (b.evaluate(m, p + dp, v).r - b.evaluate(m, p - dp, v).r) / (2 * h)
        np.testing.assert_allclose(rows.arm, num, atol=2e-5 * max(1, np.abs(num).max()),
                                   err_msg=b.kind)
        numn = np.empty((b.n_rows, b.n_nuisance))
        for j in range(b.n_nuisance):
            dv = np.zeros(b.n_nuisance)
            dv[j] = h
            numn[:, j] = (b.evaluate(m, p, v + dv).r - b.evaluate(m, p, v - dv).r) / (2 * h)
        big = max(1, np.abs(numn).max(initial=0))
        np.testing.assert_allclose(rows.nuisance, numn, atol=2e-5 * big, err_msg=b.kind)


def test_stacked_normal_equations_equal_the_dense_jacobian(arm):
    m, p, gen = arm
    blocks = _blocks(m, gen)
    nuis = [b.start(m, m.nominal) for b in blocks]
    sigma = [gen.uniform(0.5, 2.0, b.n_obs) for b in blocks]
    prob = StackedProblem(m, blocks, list(m.calibratable), sigma)
    x = prob.pack(p, nuis)
    r, A, g = prob.normal_equations(x)
    J = prob.jacobian(x)
    np.testing.assert_allclose(r, prob.residuals(x))
    np.testing.assert_allclose(A, J.T @ J, rtol=1e-10, atol=1e-8 * np.abs(A).max())
    np.testing.assert_allclose(g, J.T @ r, rtol=1e-10, atol=1e-8 * np.abs(g).max())
    # on the identifiable parameters, the arm's information with the unknowns
    # marginalised is the inverse of the covariance's arm block
    names = analyse_stack(prob, x, 1e-4).report.identifiable
    prob = StackedProblem(m, blocks, names, sigma)
    _, A, _ = prob.normal_equations(prob.pack(p, nuis))
    k = prob.k
    S = marginal_normal(A, k, np.ones(prob.n))
    cov = np.linalg.inv(A)[:k, :k]
    np.testing.assert_allclose(S @ cov, np.eye(k), atol=1e-6)


def test_start_values_recover_the_gauges():
    gen = np.random.default_rng(1)
    c = np.array([100.0, -50.0, 300.0])
    u = gen.normal(size=(10, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    L = gen.uniform(140, 160, 10)
    centre, _ = sphere_fit(c + L[:, None] * u, L)
    np.testing.assert_allclose(centre, c, atol=1e-9)
    centre, R = sphere_fit(c + 150.0 * u)
    np.testing.assert_allclose([*centre, R], [*c, 150.0], atol=1e-9)
    n = np.array([0.2, -0.3, 0.9])
    n /= np.linalg.norm(n)
    t = np.cross(n, [1.0, 0, 0])
    pts = 40.0 * n + gen.normal(size=(12, 1)) * t + gen.normal(size=(12, 1)) * np.cross(n, t)
    nf, d, rms = plane_fit(pts)
    assert abs(abs(nf @ n) - 1) < 1e-12 and abs(abs(d) - 40.0) < 1e-9 and rms < 1e-9
    with pytest.raises(ValueError):
        sphere_fit(c + 150.0 * np.column_stack([u[:, :2], np.zeros(10)]))
