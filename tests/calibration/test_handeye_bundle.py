"""The structured normal equations of the reprojection refinement: equal to the dense
``J^T W J`` of the corners' Jacobian, the Schur-complement step equal to the dense solve,
Huber's pseudo-residuals equal to scipy's robust cost; and the vectorised RANSAC
hypotheses equal to Park's closed form set by set."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize._lsq.least_squares import construct_loss_function

from kinecal.calibration.handeye import axxb
from kinecal.calibration.handeye._motions import motion_pairs
from kinecal.calibration.handeye.bundle import normal_equations, robust_residuals, schur_solve
from kinecal.calibration.handeye.camera import check_camera, project
from kinecal.calibration.handeye.errors import mean_target_pose
from kinecal.calibration.handeye.ransac import _hypotheses
from kinecal.calibration.handeye.reprojection import (
    ReprojectionProblem,
    predict_blocks,
    predict_pixels,
)
from kinecal.spatial import invert_transform, matrix_from_axis_angle, transform_from
from kinecal.vision.boards import Chessboard
from kinecal.vision.render import plan_views

K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.04, 0.0005, -0.0003, 0.0])
BOARD = Chessboard(9, 6, 20.0)


def _problem(n_int, robot, n=5):
    C = plan_views(BOARD, K, DIST, (480, 360), n, rng=2)
    X = transform_from(matrix_from_axis_angle([0.02, -0.03, 1.5]), [70.0, -20.0, 60.0])
    Y = transform_from(matrix_from_axis_angle([np.pi, 0.0, 0.3]), [650.0, -100.0, 50.0])
    F = Y @ invert_transform(C) @ invert_transform(X)
    P = np.concatenate([BOARD.object_points[: 30 + 4 * k] for k in range(n)])  # unequal counts
    counts = [30 + 4 * k for k in range(n)]
    sid = np.repeat(np.arange(n), counts)
    uv = np.concatenate([project(K, DIST, BOARD.object_points[:c] @ Ck[:3, :3].T + Ck[:3, 3])
                         for c, Ck in zip(counts, C, strict=True)])
    pr = ReprojectionProblem(F, P, uv, sid, True, K, check_camera(K, DIST)[1], X, Y, n_int,
                             robot)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    return pr, starts


@pytest.mark.parametrize("n_int,robot", [(0, None), (9, None), (12, (0.001, 0.2))])
def test_structured_normal_equations_equal_the_dense_ones(n_int, robot):
    pr, starts = _problem(n_int, robot)
    rng = np.random.default_rng(1)
    p = rng.normal(size=pr.n_params) * 1e-3
    uv, Jg, Je = predict_blocks(pr, p)
    _, J = predict_pixels(pr, p, True)
    r = uv - pr.uv + rng.normal(size=uv.shape)
    w = rng.uniform(0.2, 1.0, r.shape)
    prior = None
    Jd = (J * np.sqrt(w)[:, :, None]).reshape(-1, pr.n_params)
    rd = (r * np.sqrt(w)).ravel()
    if robot is not None:
        d = np.tile(np.r_[[1 / robot[0]] * 3, [1 / robot[1]] * 3], (pr.n, 1))
        wp, rp = rng.uniform(0.5, 1.0, d.shape), p[12 + n_int:].reshape(-1, 6) * d
        prior = (d, wp, rp)
        rows = np.zeros((6 * pr.n, pr.n_params))
        rows[:, 12 + n_int:] = np.diag((d * np.sqrt(wp)).ravel())
        Jd, rd = np.vstack([Jd, rows]), np.r_[rd, (rp * np.sqrt(wp)).ravel()]
    A, b = normal_equations(Jg, Je, w, r, starts, prior)
    scale = np.abs(Jd.T @ Jd).max()
    np.testing.assert_allclose(A, Jd.T @ Jd, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(b, Jd.T @ rd, rtol=0, atol=1e-12 * np.abs(Jd.T @ rd).max())
    damp = 1e-3 * np.diag(A)
    h = schur_solve(A, damp, b, 12 + n_int)
    np.testing.assert_allclose(h, np.linalg.solve(A + np.diag(damp), -b), rtol=1e-10,
                               atol=1e-12 * np.abs(h).max())


def test_huber_pseudo_residuals_give_scipys_cost_and_gradient_weights():
    r = np.random.default_rng(2).normal(scale=4.0, size=500)
    pseudo, w, c = robust_residuals(r, "huber", 3.0)
    rho = construct_loss_function(r.size, "huber", 3.0)(r)  # scipy's (rho, rho', rho'')
    np.testing.assert_allclose(0.5 * np.sum(pseudo**2), 0.5 * np.sum(rho[0]), rtol=1e-13)
    np.testing.assert_allclose(w, rho[1], rtol=1e-13)  # d rho / d z: the gradient's weights
    assert np.all(c[np.abs(r) > 3.0] < 1e-15) and np.all(c[np.abs(r) <= 3.0] == 1.0)


def test_ransac_hypotheses_are_parks_closed_form_set_by_set():
    rng = np.random.default_rng(3)
    n = 9
    G = transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * 0.5),
                       rng.normal(size=(n, 3)) * 100)
    C = transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * 0.5),
                       rng.normal(size=(n, 3)) * 100 + [0, 0, 500])
    subsets = np.array([[0, 1, 2], [1, 4, 7], [2, 3, 8], [0, 5, 6]])
    X, Y, keep = _hypotheses(G, C, subsets)
    assert keep.all()
    for k, s in enumerate(subsets):
        Xr = axxb.park(*motion_pairs(G[s], C[s], "all"))
        np.testing.assert_allclose(X[k], Xr, rtol=0, atol=1e-9)
        np.testing.assert_allclose(Y[k], mean_target_pose(G[s], Xr, C[s]), rtol=0, atol=1e-9)
