"""Calibrations of several kinds stay bounded: each block's unknowns are eliminated from its
own rows (the arm's factor and the noise redundancies equal their dense forms, at a memory
of one normal matrix, not one per file); more rows or unknowns than a stacked fit takes
are refused before any work; a distance that is no reading of the gauge names its row."""

from __future__ import annotations

import dataclasses
import re
import time
import tracemalloc

import numpy as np
import pytest

import kinecal
from kinecal.calibration.blocks import analysis, weights
from kinecal.calibration.blocks.api import calibrate_blocks, start_blocks
from kinecal.calibration.blocks.checks import MAX_STACK_ROWS, MAX_STACK_UNKNOWNS
from kinecal.calibration.blocks.make import make_blocks
from kinecal.calibration.blocks.simulate import simulate_kind
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.weights import initial_sigma
from kinecal.calibration.serial.problem import candidate_names
from kinecal.data import GaugeMeasurements
from kinecal.errors import InputError


@pytest.fixture(scope="module")
def mix():
    """A ballbar and 12 files of fixed points (4 points, 6 touches each) of a UR5."""
    m = kinecal.load_model("ur5")
    gen = np.random.default_rng(11)
    data = [simulate_kind(m, "ballbar", 20, noise=0.002, rng=gen).data]
    data += [simulate_kind(m, "point", 6, noise=0.01, rng=gen).data for _ in range(12)]
    blocks = make_blocks(m, data)
    nuis, _ = start_blocks(m, blocks, m.nominal)
    sig, _ = initial_sigma(blocks)
    prob = StackedProblem(m, blocks, candidate_names(m, "identifiable"), sig)
    return m, data, prob, prob.pack(m.nominal, nuis)


def _dense_jacobian(prob, x):
    return prob.jacobian(x)


def test_the_arm_factor_is_that_of_the_whole_stack(mix):
    _, _, prob, x = mix
    D, L, _, _ = analysis.stack_scale(prob, prob.params(x))
    Raa = analysis._arm_factor(prob, x, D, L, check=True)
    J = _dense_jacobian(prob, x)
    nn = prob.n - prob.k
    scaled = np.hstack([J[:, prob.k:] * np.concatenate(
        [np.full(b.n_nuisance, b.nuisance_scale(L)) for b in prob.blocks]), J[:, :prob.k] * D])
    R = np.linalg.qr(scaled, mode="r")
    # equal up to the signs of rows: compare the Gram matrices
    np.testing.assert_allclose(Raa.T @ Raa, R[nn:, nn:].T @ R[nn:, nn:], rtol=1e-9,
                               atol=1e-9 * np.abs(Raa.T @ Raa).max())


def test_redundancies_equal_the_dense_traces_at_the_memory_of_one_matrix(mix):
    _, _, prob, x = mix
    J = _dense_jacobian(prob, x)
    A = J.T @ J
    d = np.sqrt(np.diag(A))
    Ainv = np.linalg.pinv(A / np.outer(d, d), rcond=1e-12) / np.outer(d, d)
    dense = [b.n_rows - float(np.trace(Ainv @ (J[rs].T @ J[rs])))
             for b, rs in zip(prob.blocks, prob.row_slices, strict=True)]
    tracemalloc.start()
    got = weights.redundancies(prob, x)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    np.testing.assert_allclose(got, dense, rtol=1e-8, atol=1e-8)
    # one normal matrix and its inverse (and temporaries), not one (n, n) per file (13)
    assert peak < 10 * prob.n ** 2 * 8, (peak, prob.n)


def test_too_many_rows_are_refused_before_any_work():
    m = kinecal.load_model("ur5")
    n = MAX_STACK_ROWS + 2
    q = np.zeros((n, 6)) + np.linspace(0, 1, n)[:, None]
    big = GaugeMeasurements("pair", q, np.arange(n) // 2, tuple(map(str, range(n // 2))),
                            distance=np.full(n, 260.0), source="big.csv")
    t0 = time.process_time()
    with pytest.raises(InputError, match=r"200,002 rows in 1 set \(big.csv: 200,002\): more "
                       r"than the 200,000 one calibration of several kinds takes"):
        calibrate_blocks(m, [big])
    assert time.process_time() - t0 < 5  # refused before the blocks are made


def test_too_many_unknowns_are_refused_before_any_fit():
    m = kinecal.load_model("ur5")
    groups = MAX_STACK_UNKNOWNS // 3 + 1
    gen = np.random.default_rng(0)
    q = gen.uniform(-3, 3, (4 * groups, 6))
    many = GaugeMeasurements("point", q, np.repeat(np.arange(groups), 4),
                             tuple(f"S{i}" for i in range(groups)), source="many.csv")
    with pytest.raises(InputError, match=r"unknowns \(\d+ of the arm, 2,502 of the gauges' "
                       r"own in 1 set\): more than the 2,500"):
        calibrate_blocks(m, [many])


def test_the_group_check_of_many_pairs_is_one_pass():
    """500 000 pairs took 45 s in a loop over the pairs; a short pair is still named."""
    m = kinecal.load_model("ur5")
    n = 400_000
    q = np.random.default_rng(1).uniform(-3, 3, (n, 6))
    group = np.arange(n) // 2
    q[5] = q[4]  # pair 2 touched twice at one configuration
    data = GaugeMeasurements("pair", q, group, tuple(map(str, range(n // 2))),
                             distance=np.full(n, 260.0), source="p.csv")
    t0 = time.process_time()
    with pytest.raises(InputError, match=r"p.csv, row 5: pair \(p.csv\): pair '2' has 2 rows "
                       r"\(rows 5, 6\) in 1 distinct arm configuration"):
        make_blocks(m, [data])
    assert time.process_time() - t0 < 10


@pytest.mark.parametrize("kind, value", [("ballbar", 1e11), ("pair", 1e-7)])
def test_a_distance_that_is_no_reading_of_the_gauge_names_its_row(kind, value):
    """A ballbar distance of 1e11 said "rows do not determine its own unknowns"."""
    m = kinecal.load_model("ur5")
    d = simulate_kind(m, kind, 20, rng=3).data
    L = d.distance.copy()
    L[4] = value
    if kind == "pair":
        L[5] = value
    bad = dataclasses.replace(d, distance=L, source="g.csv")
    with pytest.raises(InputError, match=rf"g.csv, row 5: {kind} \(g.csv\): "
                       rf"(pair )?distance {re.escape(f'{value:.6g}')} is [0-9.e+-]+ times the "
                       r"file's median"):
        calibrate_blocks(m, [bad])


def test_the_blind_motions_need_no_square_matrix_of_the_tool_points(mix):
    """The motions the arm can produce were judged with the full left singular vectors of
    a (3N, 7) matrix: 0.75 GB for 100 files of fixed points; the peak of the analysis now
    stays within a few normal matrices."""
    _, _, prob, x = mix
    from kinecal.calibration.blocks.analysis import analyse_stack

    n_points = sum(len(b.q) for b in prob.blocks)
    tracemalloc.start()
    analyse_stack(prob, x, 1e-4)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 0.25 * (3 * n_points) ** 2 * 8, (peak, n_points)
