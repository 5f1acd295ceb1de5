"""Honest uncertainty with a near-dependence: only the parameters that take part in the
unidentified directions lose their standard error (kinecal.calibration.uncertainty)."""

import numpy as np

from kinecal.calibration.uncertainty import ESTIMABLE_TOL, subspace_uncertainty


def near_dependent(eps, k=6, m=300, seed=0):
    """A Jacobian whose columns 0 and 1 differ by `eps` (relative), partly along the
    other, random columns (so the near-null direction touches them)."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(m, k))
    J[:, 1] = J[:, 0] + eps * (rng.normal(size=m) + J[:, 2:] @ rng.uniform(-1, 1, k - 2))
    return J


def test_near_dependence_takes_the_std_of_its_pair_only():
    J = near_dependent(1e-4)
    unc = subspace_uncertainty(J.T @ J, 1.0, J.shape[0], rank=5)
    # the near-null direction touches every parameter (the old test, a component below
    # 1e-6, took every standard error away) ...
    assert (np.linalg.norm(unc.null, axis=1) > ESTIMABLE_TOL).all()
    # ... yet only the pair takes part in it
    assert unc.estimable.tolist() == [False, False, True, True, True, True]
    std = unc.std
    assert np.isinf(std[:2]).all() and np.isfinite(std[2:]).all()
    # the pair's sum is estimable, their difference is not; a row of a free column is
    ok = unc.bounded(np.array([[1.0, 1, 0, 0, 0, 0], [1.0, -1, 0, 0, 0, 0],
                               [0.0, 0, 1, 2, 0, 0]]))
    assert ok.tolist() == [True, False, True]


def test_exact_dependence_and_full_rank_are_unchanged():
    J = near_dependent(0.0)
    unc = subspace_uncertainty(J.T @ J, 1.0, J.shape[0], rank=5)
    assert unc.estimable.tolist() == [False, False, True, True, True, True]
    J = near_dependent(1e-2)
    full = subspace_uncertainty(J.T @ J, 1.0, J.shape[0], rank=6)
    assert full.estimable.all() and full.null.shape[1] == 0
    np.testing.assert_allclose(full.covariance * (J.shape[0] - 6), np.linalg.inv(J.T @ J),
                               rtol=1e-8)


def test_kept_standard_errors_match_the_spread_of_the_estimates():
    """Monte Carlo on the linear model: the pair held (the fit of the identified subspace,
    as a rank-truncated solve makes it), the others' reported std is their spread."""
    J = near_dependent(1e-4, seed=1)
    rng = np.random.default_rng(2)
    x_true = rng.normal(size=6)
    w, V = np.linalg.eigh(J.T @ J)
    P = V[:, 1:] @ np.diag(1 / w[1:]) @ V[:, 1:].T  # truncated pseudo-inverse
    est, stds = [], []
    for _ in range(400):
        y = J @ x_true + 0.1 * rng.normal(size=J.shape[0])
        x = P @ J.T @ y
        r = y - J @ x
        est.append(x)
        stds.append(subspace_uncertainty(J.T @ J, float(r @ r), J.shape[0], rank=5).std)
    est, stds = np.array(est), np.array(stds)
    spread = est[:, 2:].std(axis=0)
    ratio = spread / np.median(stds[:, 2:], axis=0)
    assert np.all((ratio > 0.85) & (ratio < 1.15)), ratio
