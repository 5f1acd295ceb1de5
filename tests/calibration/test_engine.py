"""The calibration engine's shared pieces (docs/architecture.md, "The calibration engine"):
a tracker block's normal equations accumulated chain by chain equal those of its dense
rows; the stack's analysis from the Gram matrix of tracker rows decides as the exact
factor does; a tracker file on the stack gives the serial path's answer, its noise
estimated in two rounds however far its start; the covariance step (unknowns
marginalised) and the growth test of both paths."""

import dataclasses
import importlib.metadata

import numpy as np
import pytest

import kinecal
from kinecal.calibration.blocks.analysis import analyse_stack
from kinecal.calibration.blocks.api import calibrate_blocks
from kinecal.calibration.blocks.solve import estimate_noise
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.system_simulate import simulate_system
from kinecal.calibration.blocks.tracker import TrackerBlock
from kinecal.calibration.identifiability import analyse_factor, separated_columns
from kinecal.calibration.serial.simulate import simulate
from kinecal.calibration.uncertainty import arm_uncertainty, subspace_uncertainty
from kinecal.io.urdf_tree import load_urdf_system
from kinecal.optimize.lsq import levenberg_marquardt

TIPS = ["gripper_left_base_link", "gripper_right_base_link", "head_2_link"]


@pytest.fixture(scope="module")
def talos_rows():
    dist = importlib.metadata.distribution("example-robot-data")
    path = dist.locate_file("cmeel.prefix/share/example-robot-data/robots/"
                            "talos_data/robots/talos_reduced.urdf")
    system = load_urdf_system(path, TIPS)
    data = simulate_system(system, 60, noise=1e-4, rng=5).data
    gen = np.random.default_rng(6)
    data = dataclasses.replace(data, weights=gen.uniform(0.5, 2.0, len(data)))
    block = TrackerBlock(data)
    block.start(system, system.nominal)
    return system, block


def test_chain_by_chain_normal_equations_equal_the_dense_rows(talos_rows):
    system, block = talos_rows
    prob = StackedProblem(system, [block], list(system.calibratable),
                          [block.relative_sigma()])
    assert prob.groups[0] is not None and len(prob.groups[0]) == len(TIPS)
    x = prob.pack(system.nominal + 1e-3, [np.zeros(0)])
    prob.exclude([(0, 3), (0, 70)])  # rows of weight zero are skipped, their residual 0
    r, A, g = prob.normal_equations(x)
    J = prob.jacobian(x)  # the dense weighted rows
    rd = prob.residuals(x)
    np.testing.assert_allclose(r, rd, rtol=0, atol=1e-15)
    assert np.all(r[9:12] == 0) and np.all(r[210:213] == 0)
    scale = np.abs(J.T @ J).max()
    np.testing.assert_allclose(A, J.T @ J, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(g, J.T @ rd, rtol=0, atol=1e-12 * np.abs(J.T @ rd).max())
    # the head's rows reach fewer columns than an arm's: its group is smaller
    sizes = sorted(len(cols) for _, cols in prob.groups[0])
    assert sizes[0] < sizes[-1] <= prob.k


def test_the_gram_analysis_decides_as_the_exact_factor(talos_rows):
    system, block = talos_rows
    prob = StackedProblem(system, [block], list(system.calibratable),
                          [block.relative_sigma()])
    x = prob.pack(system.nominal, [np.zeros(0)])
    gram = analyse_stack(prob, x, 1e-4)
    exact = analyse_stack(prob, x, 1e-7)  # below GRAM_TOL: the rows' TSQR factor
    again = analyse_factor(exact.reduced / exact.scale, prob.free, exact.n_rows, tol=1e-4,
                           scale=exact.scale)
    assert gram.report.identifiable == again.identifiable
    assert 40 < gram.report.rank < prob.k
    s0, s1 = gram.report.singular_values, again.singular_values
    big = s1 > 1e-6 * s1[0]  # a root of the Gram matrix keeps these to round-off
    np.testing.assert_allclose(s0[big], s1[big], rtol=1e-8)


@pytest.mark.parametrize("noise", [1e-3, 0.5])
def test_a_tracker_file_on_the_stack_gives_the_serial_answer(noise):
    m = kinecal.load_model("ur5")
    data = simulate(m, 150, noise=noise, rng=7).data
    serial = kinecal.calibrate(m, data)
    stack = calibrate_blocks(m, [data])
    assert stack.free == serial.free
    length = np.abs(serial.params).max()  # mm
    np.testing.assert_allclose(stack.params, serial.params, rtol=0, atol=1e-9 * length)
    free = m.index(serial.free)
    np.testing.assert_allclose(stack.std[free], serial.std[free], rtol=1e-6)


def test_a_common_noise_scale_is_estimated_at_once():
    """A tracker file's noise starts at 1 mm (none stated) and is 1e-3 mm: the scale
    common to every set changes no fit and is taken in one round, the second confirms."""
    m = kinecal.load_model("ur5")
    data = simulate(m, 150, noise=1e-3, rng=7).data
    serial = kinecal.calibrate(m, data)
    block = TrackerBlock(data)
    block.start(m, m.nominal)
    prob = StackedProblem(m, [block], serial.free, [np.ones(len(data))])
    res = levenberg_marquardt(prob.residuals, prob.jacobian, prob.pack(m.nominal, [[]]),
                              monitor=prob.monitor, normal_equations=prob.normal_equations)
    res, f, _, rounds = estimate_noise(prob, res, [False])
    assert rounds == 2
    np.testing.assert_allclose(f, 1.0, rtol=1e-3)
    # the noise estimated is the serial fit's residual standard deviation
    np.testing.assert_allclose(prob.sigma[0], serial.sigma, rtol=1e-6)


def test_the_covariance_step_without_unknowns_is_the_subspace_uncertainty():
    gen = np.random.default_rng(8)
    J = gen.normal(size=(60, 5)) * [1, 1, 1e-3, 1e-3, 1]
    J[:, 4] = J[:, 0] + J[:, 1]  # one exact null direction
    A, D = J.T @ J, np.array([1, 1, 1e3, 1e3, 1])
    one = arm_uncertainty(A, 2.5, 60, 5, 4, D)
    two = subspace_uncertainty(A, 2.5, 60, 4, D)
    np.testing.assert_array_equal(one.covariance, two.covariance)
    assert list(one.estimable) == [False, False, True, True, False]  # (1, 1, 0, 0, -1)
    # unknowns of a set marginalised: the Schur complement's covariance
    Jn = gen.normal(size=(60, 2))
    Jf = np.hstack([J[:, :4], Jn])
    full = arm_uncertainty(Jf.T @ Jf, 2.5, 58, 4, 4, np.r_[D[:4], 1, 1])
    Q, _ = np.linalg.qr(Jn)
    Jm = J[:, :4] - Q @ (Q.T @ J[:, :4])
    direct = subspace_uncertainty(Jm.T @ Jm, 2.5, 58, 4, D[:4])
    np.testing.assert_allclose(full.covariance, direct.covariance, rtol=1e-9)


def test_the_growth_test_frees_a_separated_column_and_never_a_confounded_one():
    gen = np.random.default_rng(9)
    J = gen.normal(size=(50, 3))
    held = np.column_stack([J[:, 0] - J[:, 1],  # confounded with the free set
                            gen.normal(size=50),  # well separated
                            J[:, 2] + 1e-6 * gen.normal(size=50)])  # barely
    B = np.linalg.qr(np.hstack([J, held]))[1]
    assert list(separated_columns(B, [0, 1, 2], [3, 4, 5], 1e-4)) == [1]
