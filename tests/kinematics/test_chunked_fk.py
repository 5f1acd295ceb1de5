"""Chunked FK kernels (`kinecal.kinematics.serial.compose`): chunked equals one pass, positions
(composed backwards) equal the frames' origins, an independent 4x4 product chain, the
half-angle trigonometry's accuracy."""

import numpy as np
import pytest

from kinecal.calibration.serial.simulate import random_configurations
from kinecal.kinematics.serial import compose
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.serial.sweep import chunked_jacobian_t
from kinecal.spatial import rot_x, rot_z, transform_from, transform_from_xyz_rpy

from .test_chain_extensions import MODELS


def _one_pass(model, q, p, kernel_out):
    """The same kernels over all poses in one chunk."""
    fn = {"positions": compose.positions, "transforms": compose.transforms}[kernel_out]
    return fn(model.motions, model._motion_index, q, p, elements=0)


@pytest.mark.parametrize("convention", list(MODELS))
def test_chunked_equals_one_pass(convention):
    rng = np.random.default_rng(21)
    model = MODELS[convention](rng)
    q = random_configurations(model, 2 * compose.CHUNK_ELEMENTS + 123, rng)
    p = model.nominal + rng.normal(0, 0.01, model.n_params)
    P = model.positions(q, p)
    np.testing.assert_allclose(P, _one_pass(model, q, p, "positions"), rtol=1e-15, atol=1e-15)
    T = model.fk(q, p)
    np.testing.assert_allclose(T, _one_pass(model, q, p, "transforms"), rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(P, T[:, :3, 3], rtol=1e-13, atol=1e-12)
    # the Jacobian in chunks of 2048 poses against one sweep of everything
    cols = np.arange(0, model.n_params, 2)
    Jc = chunked_jacobian_t(model, q, p, "pose", cols)
    Js = model.sweep(q, p).jacobian_t("pose", cols)
    np.testing.assert_allclose(Jc, Js, rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(model.sweep(q, p).positions, T[:, :3, 3], rtol=0, atol=1e-15)


def test_population_over_many_chunks():
    """P x N above the chunk size: the chunks split the poses, not the vectors."""
    rng = np.random.default_rng(22)
    model = MODELS["hayati"](rng)
    q = random_configurations(model, 301, rng)
    pop = model.nominal + rng.normal(0, 0.01, (60, model.n_params))
    Pp = model.positions(q, pop)
    assert Pp.shape == (60, 301, 3)
    for k in (0, 17, 59):
        np.testing.assert_array_equal(Pp[k], model.positions(q, pop[k]))


@pytest.mark.parametrize("name", ["ur5", "irb120", "kr6-craig"])
def test_population_frames_of_bundled_arms(name):
    """Every parameter perturbed per vector (base rotations too): frames stacked per vector
    meet frames stacked per pose in the same chain, bit for bit against one by one."""
    import kinecal

    rng = np.random.default_rng(25)
    model = kinecal.load_model(name)
    q = random_configurations(model, 70, rng)
    pop = model.nominal + rng.normal(0, 0.01, (5, model.n_params))
    T = model.fk(q, pop)
    for k in range(5):
        np.testing.assert_array_equal(T[k], model.fk(q, pop[k]))


def _dh_matrix(theta, d, a, alpha):
    return transform_from(rot_z(theta), [0, 0, d]) @ transform_from(rot_x(alpha), [a, 0, 0])


def test_positions_against_product_of_matrices():
    """Independent check: one 4x4 product per joint (standard D-H), per configuration."""
    rng = np.random.default_rng(23)
    joints = [dict(theta=rng.uniform(-1, 1), d=rng.uniform(-200, 200),
                   a=rng.uniform(-200, 200), alpha=rng.uniform(-2, 2)) for _ in range(6)]
    base = np.r_[rng.uniform(-500, 500, 3), rng.uniform(-1, 1, 3)]
    tool = [10.0, -20.0, 90.0]
    model = SerialModel("m", "dh", joints, base=base, tool=tool)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (40, 6))
    q[0] = np.pi  # the half-angle tangent's pole
    q[1] = -np.pi
    q[2] = 0.0
    want = []
    for row in q:
        T = transform_from_xyz_rpy(base)
        for j, qj in zip(joints, row, strict=True):
            T = T @ _dh_matrix(j["theta"] + qj, j["d"], j["a"], j["alpha"])
        want.append((T @ np.r_[tool, 1.0])[:3])
    np.testing.assert_allclose(model.positions(q), want, rtol=0, atol=1e-10)
    np.testing.assert_allclose(model.fk(q)[:, :3, 3], want, rtol=0, atol=1e-10)


def test_half_angle_trigonometry_accuracy():
    """cos and sin from tan(x / 2) within 4e-16 of libm's over two turns and at the poles."""
    rng = np.random.default_rng(24)
    x = np.concatenate([rng.uniform(-2 * np.pi, 2 * np.pi, 200_000),
                        np.pi + np.linspace(-1e-7, 1e-7, 101),
                        -np.pi + np.linspace(-1e-7, 1e-7, 101),
                        np.linspace(-1e-9, 1e-9, 101), [np.pi, -np.pi, 0.0]])
    model = SerialModel("one", "dh", [dict(theta=0.0, d=0.0, a=0.0, alpha=0.0)])
    values, _ = compose.motion_values(model.motions, model._motion_index, model.nominal)
    (c, s), = compose.joint_trig(model.motions, values, x[None, :]).values()
    assert np.abs(c - np.cos(x)).max() < 4e-16
    assert np.abs(s - np.sin(x)).max() < 4e-16
    small = np.abs(x) < 1e-6  # relative accuracy near zero
    np.testing.assert_allclose(s[small], np.sin(x[small]), rtol=1e-15)
