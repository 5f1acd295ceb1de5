"""The camera-pixel block of an arm calibration: analytic Jacobians against central
differences, recovery of a known arm from exact corners (both set-ups), what the camera
cannot identify in words, the board-scale and outlier diagnostics."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal import diagnostics
from kinecal.calibration.camera.block import PixelBlock
from kinecal.calibration.camera.evaluate import aligned_tool_errors
from kinecal.calibration.camera.identify import camera_identifiability
from kinecal.calibration.camera.result import Stations
from kinecal.calibration.camera.solve import calibrate_arm_camera
from kinecal.calibration.serial.simulate import random_errors
from kinecal.io.models import load_model
from kinecal.spatial import invert_transform, matrix_from_axis_angle, transform_from

K = np.array([[900.0, 0.0, 400.0], [0.0, 900.0, 300.0], [0.0, 0.0, 1.0]])
DIST = np.array([-0.1, 0.05, 0.001, -0.001, 0.01])
BOARD = np.array([[c * 25.0, r * 25.0, 0.0] for r in range(6) for c in range(9)])
HOME = np.radians([0.0, 15.0, 15.0, 0.0, 60.0, 0.0])


def _mounts(model, setup):
    X = transform_from(matrix_from_axis_angle([0.02, -0.03, np.pi / 2]), [70.0, -20.0, 60.0])
    C0 = transform_from(np.eye(3), [-100.0, -60.0, 450.0])
    F0 = model.fk(HOME)[0]
    if setup == "eye-in-hand":
        return X, F0 @ X @ C0
    Y = transform_from(matrix_from_axis_angle([0.0, np.pi, 0.2]), [10.0, -15.0, 80.0])
    return F0 @ Y @ invert_transform(C0), Y


def _stations(model, setup, truth, n=24, seed=1, board=BOARD):
    """Exact corners of `n` stations of the true arm near home, and their board poses."""
    X, Y = _mounts(model, setup)
    q = HOME + np.radians(np.random.default_rng(seed).uniform(-12, 12, (n, 6)))
    blk = PixelBlock(model, q, [board] * n, [np.zeros((len(board), 2))] * n, setup, K, DIST,
                     X, Y)
    uv = blk.predict(truth, np.zeros(12))[0]
    F = model.fk(q, truth)
    C = (invert_transform(X) @ invert_transform(F) @ Y if setup == "eye-in-hand"
         else invert_transform(X) @ F @ Y)
    return Stations(q, [BOARD] * n, np.split(uv, n), C), X, Y


@pytest.fixture(scope="module")
def kr6():
    return load_model("kr6-craig")


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_jacobians_match_central_differences(kr6, setup):
    rng = np.random.default_rng(0)
    X, Y = _mounts(kr6, setup)
    q = HOME + np.radians(rng.uniform(-10, 10, (3, 6)))
    p = kr6.nominal + rng.normal(0, 1e-2, kr6.n_params)
    blk = PixelBlock(kr6, q, [BOARD] * 3, [np.zeros((54, 2))] * 3, setup, K, DIST, X, Y,
                     n_int=12)
    nu = rng.normal(0, 1e-3, blk.n_nuisance)
    nu[12:] *= 0.01
    cols = np.arange(kr6.n_params)
    _, Ja, Jn = blk.predict(p, nu, cols, jac=True, scale_column=True)
    h = 1e-6
    for k in cols:
        d = np.zeros(kr6.n_params)
        d[k] = h
        fd = (blk.predict(p + d, nu)[0] - blk.predict(p - d, nu)[0]) / (2 * h)
        assert np.allclose(Ja[:, :, k], fd, atol=1e-5 * max(1.0, np.abs(fd).max())), \
            kr6.parameter_names[k]
    for k in range(blk.n_nuisance):
        d = np.zeros(blk.n_nuisance)
        d[k] = h
        fd = (blk.predict(p, nu + d)[0] - blk.predict(p, nu - d)[0]) / (2 * h)
        assert np.allclose(Jn[:, :, k], fd, atol=1e-5 * max(1.0, np.abs(fd).max())), k
    big = PixelBlock(kr6, q, [BOARD * (1 + h)] * 3, [np.zeros((54, 2))] * 3, setup, K, DIST,
                     X, Y, n_int=12)
    small = PixelBlock(kr6, q, [BOARD * (1 - h)] * 3, [np.zeros((54, 2))] * 3, setup, K,
                       DIST, X, Y, n_int=12)
    fd = (big.predict(p, nu)[0] - small.predict(p, nu)[0]) / (2 * h)
    assert np.allclose(Jn[:, :, -1], fd, atol=1e-5 * np.abs(fd).max())


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_identifiability_names_what_the_camera_cannot_see(kr6, setup):
    st, X, Y = _stations(kr6, setup, kr6.nominal, n=12)
    blk = PixelBlock(kr6, st.q, st.points, st.pixels, setup, K, DIST, X, Y)
    info = camera_identifiability(blk, kr6.nominal, np.zeros(12), list(kr6.calibratable))
    base, flange = ("board", "X") if setup == "eye-in-hand" else ("X", "board")
    assert info.report.rank == 17
    for name in ("alpha1", "a1", "theta1", "d1"):
        assert info.taken_up_by[name] == [base]
    for name in ("theta6", "d6", "tool.x", "tool.y", "tool.z"):
        assert info.taken_up_by[name] == [flange]
    assert info.report.confounded_with["d2"] == pytest.approx({"d3": 1.0}, abs=1e-6)
    text = "\n".join(info.sentences)
    assert text.startswith("base frame against the " + ("board pose" if base == "board"
                                                          else "camera pose"))
    assert "flange against the" in text and "scale: set by the board's size" in text
    assert info.scale_free


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_exact_corners_recover_the_identifiable_arm(kr6, setup):
    """Truth perturbed on the parameters the camera identifies: recovered to round-off."""
    free = ["a2", "alpha2", "theta2", "a3", "alpha3", "theta3", "d3", "a4", "alpha4",
            "theta4", "d4", "a5", "alpha5", "theta5", "d5", "a6", "alpha6"]
    truth = kr6.nominal + random_errors(kr6, np.random.default_rng(4), free)
    st, X, Y = _stations(kr6, setup, truth)
    res = calibrate_arm_camera(kr6, st, K, DIST, setup=setup)
    assert sorted(res.free) == sorted(free)
    idx = kr6.index(free)
    angle = kr6.is_angle()[idx]
    err = np.abs(res.params[idx] - truth[idx])
    assert err[angle].max() < 1e-9 and err[~angle].max() < 1e-6
    assert res.after_px.max() < 1e-6 < 0.05 < res.before_px.max()
    assert np.allclose(res.X, X, atol=1e-6) and np.allclose(res.board_pose, Y, atol=1e-5)
    assert not res.warnings
    q = HOME + np.radians(np.random.default_rng(9).uniform(-30, 30, (20, 6)))
    assert aligned_tool_errors(kr6, res.params, truth, q).max() < 1e-6


def test_a_wrong_board_size_is_named(kr6):
    truth = kr6.nominal + random_errors(kr6, np.random.default_rng(2), ["a2", "d4", "a3"],
                                        scale=0.2)
    st, _, _ = _stations(kr6, "eye-in-hand", truth, board=BOARD * 1.02)  # printed 2 % large
    with diagnostics.expect("board-scale", "parameter-tolerance") as found:
        res = calibrate_arm_camera(kr6, st, K, DIST)
    assert [d.code for d in found] == ["parameter-tolerance", "board-scale"]  # a3, d4 ~8 mm
    assert "-1.96 % off nominal" in found[1].message and "2.00 % too small" in found[1].message
    assert res.after_px.max() < 1e-6  # the pixels cannot tell: only the lengths can


def test_a_wrong_station_is_an_outlier(kr6):
    truth = kr6.nominal + random_errors(kr6, np.random.default_rng(3))
    st, _, _ = _stations(kr6, "eye-in-hand", truth)
    st.q[5, 1] += np.radians(1.0)  # a joint read 1 deg off
    st.pixels = [p + np.random.default_rng(k).normal(0, 0.05, p.shape)
                 for k, p in enumerate(st.pixels)]
    with diagnostics.expect("outliers", "parameter-tolerance"):  # the linear fit is pulled
        lin = calibrate_arm_camera(kr6, st, K, DIST)
    assert lin.outliers == [5]
    with diagnostics.expect("outliers", "parameter-tolerance") as found:
        rob = calibrate_arm_camera(kr6, st, K, DIST, loss="huber")
    assert [d.code for d in found] == ["outliers"]  # the final fit is within tolerances
    assert rob.outliers == [5] and "left out" in found[0].message
    keep = rob.inliers
    assert np.sqrt(np.mean(rob.after_px[keep] ** 2)) < 0.075 < \
        np.sqrt(np.mean(lin.after_px[keep] ** 2))


def test_a_grossly_wrong_station_is_left_out_from_the_start(kr6):
    """A joint read 20 deg off (a station of another pose): the robust closed-form start
    flags it, and a robust fit leaves it out from its first pass; down-weighted in the fit
    it had pulled the arm into a wrong minimum (lengths moved by metres, 28 px RMS)."""
    truth = kr6.nominal + random_errors(kr6, np.random.default_rng(4))
    st, _, _ = _stations(kr6, "eye-in-hand", truth, n=12)  # (of 24 the fit held before)
    st.q[7, 1] += np.radians(20.0)
    st.pixels = [p + np.random.default_rng(k).normal(0, 0.05, p.shape)
                 for k, p in enumerate(st.pixels)]
    with diagnostics.expect("outliers") as found:
        rob = calibrate_arm_camera(kr6, st, K, DIST, loss="huber")
    assert [d.code for d in found] == ["outliers"] and rob.outliers == [7]
    assert np.sqrt(np.mean(rob.after_px[rob.inliers] ** 2)) < 0.075
    keep = [i for i in range(len(st.q)) if i != 7]
    clean = Stations(st.q[keep], [st.points[i] for i in keep], [st.pixels[i] for i in keep],
                     st.target2cam[keep], [st.names[i] for i in keep])
    ref = calibrate_arm_camera(kr6, clean, K, DIST, loss="huber")  # the station never seen
    np.testing.assert_allclose(rob.params, ref.params, rtol=0, atol=1e-6)


def test_camera_block_mixes_with_tracker_points(kr6):
    """One problem of two kinds: the tracker sees the base-side and flange-side parameters
    the camera cannot, the camera adds its pixels; exact data recover the arm."""
    from kinecal.calibration.blocks.api import calibrate_blocks
    from kinecal.calibration.camera.residual_block import CameraBlock
    from kinecal.calibration.serial.simulate import simulate

    truth_err = random_errors(kr6, np.random.default_rng(6))
    truth = kr6.nominal + truth_err
    st, _, _ = _stations(kr6, "eye-in-hand", truth, n=12)
    cam = calibrate_blocks(kr6, [CameraBlock(st, K, DIST, "eye-in-hand")])
    tracker = simulate(kr6, 30, errors=truth_err, rng=1).data
    mix = calibrate_blocks(kr6, [CameraBlock(st, K, DIST, "eye-in-hand"), tracker])
    assert len(cam.free) == 17 and len(mix.free) > len(cam.free)
    assert {"theta1", "d1", "tool.x", "tool.y", "tool.z"} <= set(mix.free) - set(cam.free)
    q = HOME + np.radians(np.random.default_rng(9).uniform(-60, 60, (50, 6)))
    err = np.linalg.norm(kr6.positions(q, mix.params) - kr6.positions(q, truth), axis=1)
    assert err.max() < 1e-3  # mm, with the base frame: the tracker sees it
    assert mix.extra["kinds"][0]["after"]["max"] < 1e-4  # px
    assert [e["kind"] for e in mix.extra["kinds"]] == ["camera", "tracker"]


def test_nuisance_standard_errors_are_those_of_the_stacked_normal_matrix(kr6):
    """X's and the board's standard errors: ``s^2 (J^T J)^-1`` of the whole stack, in
    radians and millimetres (angles were divided twice by their column scale before)."""
    truth = kr6.nominal + random_errors(kr6, np.random.default_rng(8))
    st, _, _ = _stations(kr6, "eye-in-hand", truth)
    st.pixels = [p + np.random.default_rng(50 + k).normal(0, 0.05, p.shape)
                 for k, p in enumerate(st.pixels)]
    res = calibrate_arm_camera(kr6, st, K, DIST)
    blk = PixelBlock(kr6, st.q, st.points, st.pixels, "eye-in-hand", K, DIST, res.X,
                     res.board_pose)
    _, Ja, Jn = blk.predict(res.params, np.zeros(12), kr6.index(res.free), jac=True)
    J = np.concatenate([Ja, Jn], axis=2).reshape(2 * blk.n_corners, -1)
    r = blk.residuals(res.params, np.zeros(12)).ravel()
    cov = np.linalg.inv(J.T @ J) * (r @ r) / (r.size - J.shape[1])
    expected = np.sqrt(np.diag(cov))[len(res.free):]
    assert np.allclose(res.nuisance_std, expected, rtol=3e-3)  # increments about the start
    assert 1e-5 < np.degrees(expected[:3]).max() < 1e-2  # deg: a plausible size


def test_residuals_at_a_point_already_predicted_are_not_recomputed(kr6):
    """The stacked fit asks for the residuals where it just took a Jacobian (the solver's
    last point, for the noise estimate and the analysis), for other arm columns or none: the
    kept rows answer, the same residuals bit for bit."""
    from kinecal.calibration.camera.residual_block import CameraBlock

    truth = kr6.nominal + random_errors(kr6, np.random.default_rng(3))
    st, X, Y = _stations(kr6, "eye-in-hand", truth, n=6)
    blk = CameraBlock(st, K, DIST, "eye-in-hand")
    blk.set_references(kr6, X, Y)
    calls = []
    predict = blk.pixels.predict
    blk.pixels.predict = lambda *a, **k: calls.append(a[2:]) or predict(*a, **k)
    nu = np.zeros(blk.n_nuisance)
    cols = np.arange(5)
    rows = blk.evaluate(kr6, truth, nu, cols, jacobian=True)
    for c in (None, np.arange(3), cols):
        assert np.array_equal(blk.evaluate(kr6, truth, nu, c).r, rows.r)
    assert len(calls) == 1
    fresh = CameraBlock(st, K, DIST, "eye-in-hand")
    fresh.set_references(kr6, X, Y)
    assert fresh.evaluate(kr6, truth, nu).r.tobytes() == rows.r.tobytes()
    blk.evaluate(kr6, truth, nu, np.arange(3), jacobian=True)  # other columns: computed
    assert len(calls) == 2
