"""ISO 9283 figures against the standard's formulas computed independently, with explicit
loops over cycles in plain Python (math, no numpy), on 5 poses x 30 cycles."""

import math

import numpy as np
import pytest

from kinecal.data import RepeatedPoses
from kinecal.errors import InputError
from kinecal.metrology.iso9283 import iso9283
from kinecal.spatial import matrix_from_rpy

P, N = 5, 30


def make_test(seed=0, orientation=True):
    """Five commanded poses, 30 cycles: an offset per pose, a drift and noise."""
    rng = np.random.default_rng(seed)
    commanded = rng.uniform(-800.0, 800.0, (P, 3))
    offset = rng.normal(0.0, 0.2, (P, 3))
    measured = (commanded[:, None, :] + offset[:, None, :]
                + rng.normal(0.0, 0.02, (P, N, 3)) + np.linspace(0, 0.01, N)[None, :, None])
    rot_c = rot_m = None
    if orientation:
        # within +-1.5 rad: no difference of angles reaches 180 deg (no wrap; see below)
        abc_c = rng.uniform(-1.5, 1.5, (P, 3))
        abc_m = abc_c[:, None, :] + rng.normal(0.0, 2e-4, (P, N, 3)) + 1e-3
        rot_c, rot_m = matrix_from_rpy(abc_c), matrix_from_rpy(abc_m)
    return RepeatedPoses(tuple(f"P{i + 1}" for i in range(P)), np.arange(1, N + 1), measured,
                         commanded, rot_m, rot_c)


def angles(R):
    """(a, b, c) of R = Rz(c) Ry(b) Rx(a), by the textbook formulas (away from b = +-90)."""
    return (math.atan2(R[2][1], R[2][2]), -math.asin(R[2][0]), math.atan2(R[1][0], R[0][0]))


def mean(v):
    return sum(v) / len(v)


def sample_std(v):
    m = mean(v)
    return math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))


def hand_pose(data, i):
    """AP, APx..z, RP and the angle figures of pose i, clause 7.2, by loops."""
    pts = [[float(v) for v in data.measured[i, j]] for j in range(N)]
    c = [float(v) for v in data.commanded[i]]
    bary = [mean([p[k] for p in pts]) for k in range(3)]
    ap_xyz = [bary[k] - c[k] for k in range(3)]
    lj = [math.sqrt(sum((p[k] - bary[k]) ** 2 for k in range(3))) for p in pts]
    out = {"AP": math.sqrt(sum(d * d for d in ap_xyz)), "APx": ap_xyz[0], "APy": ap_xyz[1],
           "APz": ap_xyz[2], "RP": mean(lj) + 3.0 * sample_std(lj)}
    abc = [angles(data.measured_rotations[i, j].tolist()) for j in range(N)]
    abc_c = angles(data.commanded_rotations[i].tolist())
    for k, name in enumerate("abc"):
        series = [a[k] for a in abc]
        out[f"AP{name}"] = mean(series) - abc_c[k]
        out[f"RP{name}"] = 3.0 * sample_std(series)
    return out


def hand_distance(data, i, k):
    """AD, AD_x..z, RD, RD_x..z and the angle ones between poses i and k, clause 7.3."""
    d = [math.dist(data.measured[i, j].tolist(), data.measured[k, j].tolist())
         for j in range(N)]
    dc = math.dist(data.commanded[i].tolist(), data.commanded[k].tolist())
    out = {"D_commanded": dc, "D_mean": mean(d), "AD": mean(d) - dc, "RD": 3 * sample_std(d)}
    for a in range(3):
        dj = [abs(float(data.measured[i, j, a] - data.measured[k, j, a])) for j in range(N)]
        out[f"AD{'xyz'[a]}"] = mean(dj) - abs(float(data.commanded[i, a] - data.commanded[k, a]))
        out[f"RD{'xyz'[a]}"] = 3 * sample_std(dj)
    abc_i = [angles(data.measured_rotations[i, j].tolist()) for j in range(N)]
    abc_k = [angles(data.measured_rotations[k, j].tolist()) for j in range(N)]
    ci, ck = (angles(data.commanded_rotations[m].tolist()) for m in (i, k))
    for a in range(3):
        dj = [abs(abc_i[j][a] - abc_k[j][a]) for j in range(N)]
        out[f"AD{'abc'[a]}"] = mean(dj) - abs(ci[a] - ck[a])
        out[f"RD{'abc'[a]}"] = 3 * sample_std(dj)
    return out


def test_pose_and_distance_figures_equal_the_hand_computed_ones():
    data = make_test()
    res = iso9283(data)
    assert res.pairs == [(i, k) for i in range(P) for k in range(i + 1, P)]
    for i in range(P):
        want = hand_pose(data, i)
        for key, value in want.items():
            assert res.poses[key][i] == pytest.approx(value, abs=1e-9), (i, key)
    for (i, k), got in zip(res.pairs, res.distances, strict=True):
        want = hand_distance(data, i, k)
        assert set(got) == set(want)
        for key, value in want.items():
            assert got[key] == pytest.approx(value, abs=1e-9), (i, k, key)
    # a real test, not a trivial one: AP of order the offsets, RP of order 3-4 sigma
    assert 0.05 < res.poses["AP"].mean() < 1.0 and 0.04 < res.poses["RP"].mean() < 0.2


def test_json_dict_in_degrees_with_the_contract_keys():
    data = make_test(1)
    d = iso9283(data, [(1, 3)]).to_dict()
    assert d["cycles"] == N and d["angle_unit"] == "deg" and d["length_unit"] == "mm"
    first = d["poses"][0]
    assert list(first)[:6] == ["pose", "AP", "APx", "APy", "APz", "RP"]
    assert first["RPa"] == pytest.approx(math.degrees(hand_pose(data, 0)["RPa"]), abs=1e-9)
    (dist,) = d["distances"]
    assert dist["poses"] == ["P2", "P4"]
    assert dist["RDc"] == pytest.approx(math.degrees(hand_distance(data, 1, 3)["RDc"]), abs=1e-9)


def test_known_offsets_are_recovered_exactly():
    """Symmetric scatter about commanded + offset: AP is the offset, RP is l + 3 * 0."""
    commanded = np.array([[100.0, 0.0, 50.0], [0.0, 200.0, 50.0]])
    offset = np.array([[0.3, -0.4, 0.0], [0.0, 0.0, -0.05]])
    signs = np.array([1.0, -1.0] * 5)  # +-0.01 along x: barycentre unmoved, l_j = 0.01
    measured = commanded[:, None] + offset[:, None] + 0.01 * signs[None, :, None] * [1, 0, 0]
    res = iso9283(RepeatedPoses(("a", "b"), np.arange(10), measured, commanded))
    np.testing.assert_allclose(res.poses["AP"], [0.5, 0.05], rtol=1e-12)
    np.testing.assert_allclose(res.poses["RP"], [0.01, 0.01], rtol=1e-9)
    (dist,) = res.distances
    # the two poses move together cycle by cycle: the distance never varies, RD = 0
    assert dist["RD"] == pytest.approx(0.0, abs=1e-12)


def test_orientation_near_180_degrees_is_not_split():
    """c = +-180 deg: measured angles on both sides of the cut are wrapped, not 360 apart."""
    rng = np.random.default_rng(2)
    c = np.pi + rng.normal(0.0, 1e-3, (1, 20))
    abc = np.stack([np.zeros_like(c), np.zeros_like(c), c], axis=-1)
    data = RepeatedPoses(("p",), np.arange(20), np.zeros((1, 20, 3)), np.zeros((1, 3)),
                         matrix_from_rpy(abc), matrix_from_rpy(np.array([[0.0, 0.0, np.pi]])))
    res = iso9283(data)
    wrapped = (c - np.pi)[0]
    assert res.poses["RPc"][0] == pytest.approx(3 * wrapped.std(ddof=1), rel=1e-9)
    assert res.poses["APc"][0] == pytest.approx(wrapped.mean(), abs=1e-12)


def test_bad_tests_are_refused():
    one = RepeatedPoses(("a",), np.array([1]), np.zeros((1, 1, 3)), np.zeros((1, 3)))
    with pytest.raises(InputError, match="at least 2"):
        iso9283(one)
    with pytest.raises(InputError, match="expected shape"):
        RepeatedPoses(("a", "b"), np.arange(3), np.zeros((1, 3, 3)), np.zeros((2, 3)))
    with pytest.raises(InputError, match="two different poses"):
        iso9283(make_test(orientation=False), [(0, 0)])


def test_a_long_test_pairs_consecutive_poses_in_time_and_memory_linear_in_it():
    """2000 poses took more than 120 s and 2.8 GB (every pair, each recomputing every
    pose's angles), 20 000 a MemoryError: up to 45 poses every pair, beyond each pose with
    the next; the figures of a pair are those of the pair computed alone (hand check)."""
    import time
    import tracemalloc

    from kinecal.metrology.iso9283 import MAX_DEFAULT_PAIRS, default_pairs

    assert len(default_pairs(45)) == 990 <= MAX_DEFAULT_PAIRS
    assert default_pairs(46) == [(i, i + 1) for i in range(45)]
    rng = np.random.default_rng(4)
    p, n = 3000, 3
    commanded = rng.uniform(-800.0, 800.0, (p, 3))
    measured = commanded[:, None, :] + rng.normal(0.0, 0.02, (p, n, 3))
    rot_c = matrix_from_rpy(rng.uniform(-1.5, 1.5, (p, 3)))
    data = RepeatedPoses(tuple(f"P{i + 1}" for i in range(p)), np.arange(1, n + 1), measured,
                         commanded, np.repeat(rot_c[:, None], n, axis=1), rot_c)
    t0 = time.process_time()
    tracemalloc.start()
    res = iso9283(data, check=False)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert time.process_time() - t0 < 30 and peak < 100e6, peak
    assert res.pairs == [(i, i + 1) for i in range(p - 1)]
    alone = iso9283(data, [(1500, 1501)], check=False).distances[0]
    assert res.distances[1500] == alone
    with pytest.raises(InputError, match="10,001 pose pairs: expected at most 10,000"):
        iso9283(data, [(0, 1)] * 10_001, check=False)
