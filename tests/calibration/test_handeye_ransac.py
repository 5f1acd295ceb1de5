"""RANSAC start of the robust refinement: 50 % outlier stations (KNOWN-DEFECTS)."""

from __future__ import annotations

import numpy as np

from kinecal.calibration.handeye import calibrate_handeye, solve
from kinecal.calibration.handeye.errors import pose_error
from kinecal.calibration.handeye.ransac import consensus_start
from kinecal.calibration.handeye.refine import lm
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    matrix_from_rpy,
    transform_from,
)

X_TRUE = transform_from(matrix_from_rpy([0.1, -0.25, 1.3]), [30.0, -20.0, 80.0])
Y_TRUE = transform_from(matrix_from_rpy([0.0, 0.03, 0.4]), [600.0, 100.0, 0.0])


def _stations(rng, n=20, frac=0.5):
    """bench_handeye's wide-spread stations; a fraction corrupted by 3 deg / 10 mm."""
    look = matrix_from_rpy([np.pi, 0.0, 0.0])
    R = matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(25)) @ look
    p = np.column_stack([rng.uniform(-60, 60, (n, 2)), rng.uniform(370, 430, n)])
    cam = transform_from(R, p)
    G = Y_TRUE @ cam @ invert_transform(X_TRUE)
    C = invert_transform(cam) @ transform_from(
        matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(0.1)),
        rng.normal(size=(n, 3)) * 0.5)
    k = round(frac * n)
    bad = rng.choice(n, k, replace=False)
    ax = rng.normal(size=(k, 3))
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    d = rng.normal(size=(k, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    C[bad] = C[bad] @ transform_from(matrix_from_axis_angle(ax * np.radians(3.0)), d * 10.0)
    return G, C, np.sort(bad)


def test_half_the_stations_outliers():
    """At 50 % outliers the default robust refinement reaches the error of a refinement on
    the true inliers (LM from the all-station closed form alone: ~5x worse)."""
    rng = np.random.default_rng(1)
    ours, plain, oracle, found = [], [], [], 0
    for _ in range(8):
        G, C, bad = _stations(rng)
        res = calibrate_handeye(G, C)
        ours.append(pose_error(res.X, X_TRUE))
        X0, Y0 = solve(G, C, "park")
        plain.append(pose_error(lm(G, C, X0, Y0).X, X_TRUE))
        good = np.setdiff1d(np.arange(20), bad)
        Xg, Yg = solve(G[good], C[good], "park")
        oracle.append(pose_error(lm(G[good], C[good], Xg, Yg).X, X_TRUE))
        found += set(bad) <= set(res.outliers)
    ours, plain, oracle = (np.median(v, axis=0) for v in (ours, plain, oracle))
    assert ours[1] < 1.3 * oracle[1] and ours[0] < 1.3 * oracle[0], (ours, oracle)
    assert plain[1] > 3 * ours[1]
    assert found >= 7


def test_few_outliers_unchanged_and_deterministic():
    rng = np.random.default_rng(2)
    G, C, bad = _stations(rng, frac=0.1)
    a = calibrate_handeye(G, C, seed=3)
    b = calibrate_handeye(G, C, seed=3)
    assert np.array_equal(a.X, b.X) and a.outliers == b.outliers == list(bad)
    X0, Y0 = solve(G, C, "park")
    assert pose_error(a.X, lm(G, C, X0, Y0).X)[1] < 1e-6


def test_consensus_start_on_minimal_sets():
    rng = np.random.default_rng(3)
    G, C, bad = _stations(rng, frac=0.55)
    cs = consensus_start(G, C, (np.radians(0.1), 0.5), seed=0)
    assert set(cs.inliers).isdisjoint(bad) and len(cs.inliers) >= 7
    assert cs.hypotheses > 100
    assert consensus_start(G[:4], C[:4], (0.01, 1.0)) is None
