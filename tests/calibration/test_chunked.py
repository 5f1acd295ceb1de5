"""Chunked passes (normal equations, TSQR factors) give the numbers of the full matrices."""

import numpy as np
import pytest
import scipy.linalg
import scipy.stats

import kinecal
import kinecal.calibration.serial.rows as rows_mod
from kinecal.calibration.identifiability import analyse, analyse_factor, pivoted_qr_diagonal
from kinecal.calibration.serial.problem import CalibrationProblem, analyse_poses
from kinecal.calibration.serial.simulate import simulate
from kinecal.calibration.serial.solve import _significant
from kinecal.data import Measurements
from kinecal.optimize.factor import gram_root, qr_update


@pytest.fixture
def tiny_chunks(monkeypatch):
    """Chunks of 16 poses: many chunk boundaries on small data."""
    monkeypatch.setattr(rows_mod, "CHUNK_BYTES", 1)


def _weighted_pose_data():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 90, errors="random", noise=0.01, rng=4, orientation=True,
                   angle_noise=1e-3)
    w = np.random.default_rng(5).uniform(0.5, 2.0, 90)
    return m, Measurements(sim.data.q, sim.data.xyz, w, rotations=sim.data.rotations)


@pytest.mark.parametrize("kind", ["position", "pose+weights"])
def test_chunked_normal_equations_equal_full_jacobian(kind, tiny_chunks):
    if kind == "position":
        m = kinecal.load_model("ur5")
        data = simulate(m, 100, errors="random", noise=0.01, rng=1).data
    else:
        m, data = _weighted_pose_data()
    pr = CalibrationProblem(m, data, list(m.calibratable))
    x = pr.x0 + np.random.default_rng(2).normal(0, 1e-3, pr.n_free)
    assert pr.pose_rows.chunk_poses(pr.n_free) == 16
    r, A, g = pr.normal_equations(x)
    r_full, J = pr.residuals(x), pr.jacobian(x)
    np.testing.assert_allclose(r, r_full, rtol=0, atol=1e-12 * np.abs(r_full).max())
    scale = np.abs(J.T @ J).max()
    np.testing.assert_allclose(A, J.T @ J, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(g, J.T @ r_full, rtol=0, atol=1e-12 * np.abs(J.T @ r_full).max())
    G = pr.gram(x)
    np.testing.assert_allclose(G[:-1, :-1], A, rtol=0, atol=1e-13 * scale)
    R, r2, _ = pr.pose_rows.factor(pr.full(x), pr.index)
    Jr = np.column_stack([J, r_full])
    np.testing.assert_allclose(R.T @ R, Jr.T @ Jr, rtol=0, atol=1e-12 * np.abs(Jr.T @ Jr).max())
    np.testing.assert_array_equal(r2, r)


def test_qr_update_and_gram_root_reproduce_the_gram_matrix():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(500, 7))
    R = None
    for s in range(0, 500, 37):
        R = qr_update(R, J[s:s + 37])
    np.testing.assert_allclose(R, np.triu(R))
    np.testing.assert_allclose(np.abs(R), np.abs(scipy.linalg.qr(J, mode="r")[0][:7]),
                               rtol=1e-12)
    B = gram_root(J.T @ J)
    np.testing.assert_allclose(B.T @ B, J.T @ J, rtol=1e-12)


def test_pivoted_qr_matches_lapack_without_ties():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(60, 12)) * rng.uniform(0.1, 10, 12)
    diag, piv = pivoted_qr_diagonal(A)
    _, R, piv_ref = scipy.linalg.qr(A, mode="economic", pivoting=True)
    np.testing.assert_array_equal(piv, piv_ref)
    np.testing.assert_allclose(diag, np.abs(np.diag(R)), rtol=1e-12)


def test_ties_keep_the_last_column_whatever_the_row_order():
    rng = np.random.default_rng(4)
    J = rng.normal(size=(300, 5))
    J = np.column_stack([J[:, 0], J[:, 1], J[:, 0], J[:, 2], J[:, 1], J[:, 3], J[:, 4]])
    names = [f"p{i}" for i in range(7)]
    for perm in (np.arange(300), rng.permutation(300)):
        rep = analyse(J[perm], names)
        assert rep.unidentifiable == ["p0", "p1"]
        assert rep.confounded_with == {"p0": {"p2": pytest.approx(1.0)},
                                       "p1": {"p4": pytest.approx(1.0)}}


def test_identifiability_from_chunks_equals_full_matrix(tiny_chunks):
    m = kinecal.load_model("ur5")
    data = simulate(m, 200, errors="zero", rng=3).data
    names = list(m.calibratable)
    rep = analyse_poses(m, data, names)
    J = m.identification_jacobian(data.q)[:, :, m.index(names)].reshape(-1, len(names))
    L = np.sqrt((np.linalg.norm(data.xyz - data.xyz.mean(0), axis=1) ** 2).mean())
    f = np.where(m.is_angle()[m.index(names)], 1.0 / L, 1.0)
    ref = analyse(J, names, scale=f)
    assert rep.identifiable == ref.identifiable and rep.rank == ref.rank
    assert rep.confounded_with.keys() == ref.confounded_with.keys()
    for n, combo in ref.confounded_with.items():
        assert rep.confounded_with[n] == pytest.approx(combo, rel=1e-9, abs=1e-12)
    # independent check of the numbers: SVD and least squares on the full scaled matrix
    Js = J * f
    np.testing.assert_allclose(rep.singular_values, np.linalg.svd(Js, compute_uv=False),
                               rtol=1e-10, atol=1e-12 * np.linalg.norm(Js, 2))
    kept = [names.index(n) for n in rep.identifiable]
    s = np.linalg.svd(Js[:, kept], compute_uv=False)
    assert rep.condition_number == pytest.approx(s[0] / s[-1], rel=1e-10)
    for n, combo in rep.confounded_with.items():
        c = np.linalg.lstsq(J[:, kept], J[:, names.index(n)], rcond=None)[0]
        for name, v in combo.items():
            assert v == pytest.approx(c[rep.identifiable.index(name)], rel=1e-8)
    # the Gram-root factor (for decisions at 1e-4) finds the same identifiable set
    rep_g = analyse_factor(gram_root(J.T @ J), names, J.shape[0], tol=1e-4, scale=f)
    assert rep_g.identifiable == analyse(J, names, tol=1e-4, scale=f).identifiable


@pytest.mark.parametrize("case", ["irb120-growth", "pose+weights"])
def test_calibration_does_not_depend_on_chunking(case, monkeypatch):
    if case == "irb120-growth":
        m = kinecal.load_model("irb120")
        data = simulate(m, 60, errors="random", noise=0.01, rng=0).data
    else:
        m, data = _weighted_pose_data()
    ref = kinecal.calibrate(m, data)
    monkeypatch.setattr(rows_mod, "CHUNK_BYTES", 1)
    res = kinecal.calibrate(m, data)
    assert res.free == ref.free
    # The cost is flat to its round-off floor (FK round-off ~1e-13 mm makes it noisy at
    # ~1e-12 relative) over a small region along the weakest direction (condition ~8e3 on
    # the IRB-120): chunk sums that round differently end anywhere in it, 1e-6 of a
    # parameter's standard error at most; parameters held fixed stay bit-identical.
    free = ref.std > 0
    assert (np.abs(res.params - ref.params)[free] <= 1e-5 * ref.std[free]).all()
    np.testing.assert_array_equal(res.params[~free], ref.params[~free])
    assert res.calibration_stats["after"]["rms"] == pytest.approx(
        ref.calibration_stats["after"]["rms"], rel=1e-9)
    np.testing.assert_allclose(res.std, ref.std, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(res.covariance, ref.covariance, rtol=0,
                               atol=1e-6 * np.abs(ref.covariance).max())
    assert res.identifiability.condition_number == pytest.approx(
        ref.identifiability.condition_number, rel=1e-6)


def test_covariance_is_sigma2_pinv_of_the_full_normal_matrix():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 50, errors="random", noise=0.02, rng=2)
    res = kinecal.calibrate(m, sim.data)
    pr = CalibrationProblem(m, sim.data, res.free)
    x = res.params[pr.index]
    r, J = pr.residuals(x), pr.jacobian(x)
    sigma2 = (r @ r) / (r.size - len(res.free))
    np.testing.assert_allclose(res.covariance, sigma2 * np.linalg.inv(J.T @ J), rtol=1e-7)
    assert res.sigma == pytest.approx(np.sqrt(sigma2), rel=1e-9)


def test_f_test_quantile_matches_scipy_stats():
    for k, dof in ((1, 10), (3, 150), (5, 3_000_000)):
        q = scipy.stats.f.ppf(0.99, k, dof)
        assert _significant(1.0 + 1.0001 * q * k / dof, 1.0, k, dof)
        assert not _significant(1.0 + 0.9999 * q * k / dof, 1.0, k, dof)
