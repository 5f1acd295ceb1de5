"""Several markers per pose are one pose: outlier tests, warnings, folds, pose counts, and a
bad pose that must not change the free set (kinecal.calibration.serial.inliers)."""

import dataclasses
import json
from types import SimpleNamespace

import numpy as np
import pytest

from kinecal import calibrate, simulate
from kinecal.calibration.diagnostics._common import chi_outliers
from kinecal.calibration.diagnostics.observations import describe_poses, pose_groups
from kinecal.calibration.serial.cross_validation import fold_of
from kinecal.cli import main
from kinecal.diagnostics import collect
from kinecal.io.measurements import write_measurements
from kinecal.io.models import load_model, save_model
from kinecal.kinematics.serial.markers import with_markers

POINTS = {"A": [0.0, 0.0, 31.0], "B": [52.0, -3.0, 20.0], "C": [-4.0, 61.0, 25.0]}
NOISE = 0.5  # mm per coordinate (motion capture)


@pytest.fixture(scope="module")
def three_markers():
    """A UR5 whose three markers the model file does not know (they start at its tool
    point, on the last axis: theta5 and alpha5 become identifiable only at the identified
    geometry), 35 poses x 3 markers, and the same data with one pose's joint 2 read 3 deg
    off (all three of its rows bad)."""
    arm = load_model("ur5")
    nominal = with_markers(arm, list(POINTS))
    truth = arm.with_markers(POINTS)
    sim = simulate(truth, 35, noise=NOISE, rng=11)
    val = simulate(truth, 100, errors=sim.true_params - truth.nominal, noise=NOISE,
                   rng=12).data
    q = np.array(sim.data.q)
    bad = np.flatnonzero(np.all(q == q[81], axis=1))
    q[bad, 1] += np.radians(3.0)
    return SimpleNamespace(arm=arm, nominal=nominal, clean=sim.data,
                           bad_data=dataclasses.replace(sim.data, q=q), bad=bad, val=val,
                           truth=sim.true_params)


def test_pose_groups_join_markers_and_keep_repeats_apart():
    q = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.5, 1.0], [0.0, 1.0], [0.0, 1.0]])
    marker = np.array([0, 1, 2, 0, 0, 1])
    group, n = pose_groups(q, marker)
    # rows 0-2: one pose at three markers; row 3 another pose; rows 4-5 repeat the first
    # pose's markers A and B: a second measurement of that pose
    np.testing.assert_array_equal(group, [0, 0, 0, 1, 2, 2])
    assert n == 3
    assert pose_groups(q)[0].tolist() == [0, 1, 2, 3, 4, 5]  # one tool point: rows
    assert describe_poses([0, 1, 2, 3], group) == (2, "rows 0-2; row 3")
    assert describe_poses([3], group) == (1, "3")


def test_chi_outliers_with_pooled_components():
    rng = np.random.default_rng(0)
    d = np.linalg.norm(rng.normal(size=(40, 3)), axis=1)
    d[7] = 12.0
    assert chi_outliers(d, 3) == chi_outliers(d, np.full(40, 3)) == [7]
    # a pose of 3 markers (9 components) with errors of 2 sigma on each row is not an
    # outlier among single rows; one of 7 sigma on each row is
    k = np.full(40, 3)
    k[3] = 9
    d2 = d.copy()
    d2[7] = np.linalg.norm(rng.normal(size=3))
    d2[3] = np.sqrt(3 * 2.0**2 * 3)
    assert chi_outliers(d2, k) == []
    d2[3] = np.sqrt(3 * 7.0**2 * 3)
    assert chi_outliers(d2, k) == [3]


def test_folds_deal_poses_not_rows():
    q = np.repeat(np.arange(12.0)[:, None], 3, axis=0) * [1.0, 0.5]
    marker = np.tile([0, 1, 2], 12)
    folds = fold_of(36, 5, pose_groups(q, marker))
    assert all(np.unique(folds[3 * i:3 * i + 3]).size == 1 for i in range(12))
    assert sorted(np.bincount(folds).tolist()) == [6, 6, 6, 9, 9]


def test_one_bad_pose_keeps_the_free_set(three_markers):
    t = three_markers
    nominal, clean, bad_data, bad, val = t.nominal, t.clean, t.bad_data, t.bad, t.val
    good = np.setdiff1d(np.arange(len(clean)), bad)
    ref = calibrate(nominal, clean.subset(good), validate=val)
    assert {"theta5", "alpha5"} <= set(ref.free)  # grown at the identified geometry
    for loss in ("linear", "soft_l1"):
        with collect() as found:
            res = calibrate(nominal, bad_data, validate=val, loss=loss)
        # the F-test of the growth saw the bad pose's 23 mm and held theta5, alpha5
        assert res.free == ref.free, loss
        assert res.outliers == t.bad.tolist()
        if loss == "linear":
            [w] = [w for w in found if w.code == "outliers"]
            assert w.message.startswith("1 pose (rows 81-83; 0-based) has an error")
        else:  # left out of the last fit: the good poses fit as without the bad one
            assert not [w for w in found if w.code == "outliers"]
            robust = calibrate(nominal, clean.subset(good), validate=val, loss=loss)
            np.testing.assert_allclose(res.errors_after[good], robust.errors_after, rtol=0,
                                       atol=0.05 * NOISE)
            assert abs(res.val_after.mean() / ref.val_after.mean() - 1) < 0.01


def test_identifiability_of_data_frees_what_calibrate_frees(three_markers, tmp_path, capsys):
    t = three_markers
    arm, nominal, clean, bad_data = t.arm, t.nominal, t.clean, t.bad_data
    save_model(arm, tmp_path / "arm.yaml")
    for name, data in (("clean", clean), ("bad", bad_data)):
        path = tmp_path / f"{name}.csv"
        write_measurements(path, data, nominal)
        assert main(["identifiability", str(tmp_path / "arm.yaml"), "--data", str(path),
                     "--json"]) == 0
        ident = json.loads(capsys.readouterr().out)
        assert main(["calibrate", str(tmp_path / "arm.yaml"), str(path), "--json"]) == 0
        cal = json.loads(capsys.readouterr().out)
        assert ident["identifiable"] == cal["free"], name
        assert ident["rank"] == len(cal["free"]) == 31


def test_few_poses_counts_poses_not_marker_rows():
    model = load_model("irb120").with_markers(POINTS)
    sim = simulate(model, 6, rng=3)  # 6 configurations x 3 markers
    with collect() as found:
        calibrate(model, sim.data)
    [w] = [w for w in found if w.code == "few-poses"]
    assert w.message.startswith("6 distinct poses (18 rows, 3 markers each) give 54 "
                                "equations"), w.message


def test_identifiability_of_a_mix_frees_what_calibrate_frees():
    """Ballbar and socket touches of an IRB-120 whose three markers the model file does not
    know: the analysis at nominal holds parameters the identified geometry frees
    (calibrate_blocks frees 21; the analysis alone said 19)."""
    from kinecal.calibration.blocks.api import calibrate_blocks
    from kinecal.calibration.blocks.plan import analyse_kinds
    from kinecal.calibration.blocks.simulate import simulate_kind
    from kinecal.calibration.serial.simulate import random_errors

    arm = load_model("irb120")
    truth_model = arm.with_markers(POINTS)
    gen = np.random.default_rng(7)
    truth = truth_model.nominal + random_errors(truth_model, gen)
    sets = [simulate_kind(truth_model, k, n, true_params=truth, rng=gen, noise=s).data
            for k, n, s in (("ballbar", 20, 0.002), ("point", 8, 0.01))]
    nominal = with_markers(arm, list(POINTS))
    res = calibrate_blocks(nominal, sets, sigma=[0.002, 0.01])
    ana = analyse_kinds(nominal, sets, "all", sigma=[0.002, 0.01])[0]
    assert ana.report.identifiable == res.free
    assert len(res.free) == 21


def test_a_bad_pose_in_a_mix_is_named_once(three_markers):
    from kinecal.calibration.blocks.api import calibrate_blocks
    from kinecal.calibration.blocks.simulate import simulate_kind

    t = three_markers
    truth = t.arm.with_markers(POINTS)  # the ballbar measures the same arm
    bb = simulate_kind(truth, "ballbar", 20, true_params=t.truth, rng=5, noise=0.002).data
    with collect() as found:
        res = calibrate_blocks(t.nominal, [dataclasses.replace(t.bad_data, source="t.csv"),
                                           bb])
    [w] = [w for w in found if w.code == "outliers"]
    assert w.message.startswith("1 pose (t.csv:82-84) far outside"), w.message
    assert res.outliers == t.bad.tolist()
