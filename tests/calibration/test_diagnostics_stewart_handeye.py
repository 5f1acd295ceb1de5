"""Plausibility diagnostics of Stewart-platform and hand-eye calibrations: each on data made
to trigger it and on clean data that must stay silent."""

import json

import numpy as np
import pytest

from kinecal import diagnostics
from kinecal.calibration.handeye import calibrate_handeye
from kinecal.calibration.handeye.errors import pose_error
from kinecal.calibration.handeye.poses import random_poses, star_polygon_poses
from kinecal.calibration.stewart.calibrate import (
    StewartData,
    calibrate_stewart,
    perturb_geometry,
    simulate_stewart,
)
from kinecal.errors import InputError
from kinecal.experiments.li2024 import X_TRUE, _measure
from kinecal.io.geometry import load_geometry
from kinecal.spatial import matrix_from_axis_angle, transform_from


def codes(found):
    return sorted({d.code for d in found})


# ------------------------------------------------------------------ Stewart platform
@pytest.fixture(scope="module")
def cmm():
    nominal = load_geometry("liu2008-cmm")
    true = perturb_geometry(nominal, 1e-3, 0)
    return nominal, true, simulate_stewart(true, 40, rng=1), simulate_stewart(true, 20, rng=2)


def stewart(nominal, data, **kw):
    with diagnostics.collect() as found:
        res = calibrate_stewart(nominal, data, **kw)
    assert codes(res.warnings) == codes(found)
    return res, codes(found)


def test_stewart_clean_data_is_silent_and_reports_units(cmm):
    nominal, _, cal, val = cmm
    res, found = stewart(nominal, cal, validate=val)
    assert found == [] and res.bounded and np.isfinite(res.std).all()
    # a geometry in metres: the summary in mm by default (--unit auto), in m on request
    assert " mm " in res.summary() and "leg rms before" in res.summary()
    assert " m " in res.summary("m") and " mm " not in res.summary("m")
    d = res.to_dict()
    assert d["warnings"] == [] and d["length_unit"] == "m"
    json.dumps(d)


def test_stewart_identical_and_too_few_rows_are_refused(cmm):
    nominal, _, cal, _ = cmm
    same = StewartData(np.repeat(cal.poses[:1], 60, 0), np.repeat(cal.legs[:1], 60, 0))
    with diagnostics.collect() as found, pytest.raises(InputError, match="too-few-poses"):
        calibrate_stewart(nominal, same)
    assert codes(found) == ["duplicate-poses"]
    seven = StewartData(cal.poses[:7], cal.legs[:7])  # 42 equations for 42 unknowns
    with diagnostics.collect(), pytest.raises(InputError, match="too-few-poses"):
        calibrate_stewart(nominal, seven)
    assert stewart(nominal, StewartData(cal.poses[:12], cal.legs[:12]))[1] == ["few-poses"]


def test_stewart_duplicated_rows_keep_their_standard_errors(cmm):
    nominal, _, cal, _ = cmm
    ref, _ = stewart(nominal, cal)
    dup, found = stewart(nominal, StewartData(np.repeat(cal.poses, 3, 0),
                                              np.repeat(cal.legs, 3, 0)))
    assert found == ["duplicate-poses"]
    np.testing.assert_allclose(dup.std, ref.std, rtol=1e-6)


def test_stewart_millimetres_and_radians(cmm):
    nominal, _, cal, _ = cmm
    mm = cal.poses.copy()
    mm[:, :3] *= 1000.0
    res, found = stewart(nominal, StewartData(mm, cal.legs * 1000.0))
    assert "scale-mismatch" in found
    assert "millimetres in a metre geometry" in res.warnings[0].message
    assert "scale-mismatch" in stewart(nominal, StewartData(cal.poses, cal.legs * 1000.0))[1]
    rad = cal.poses.copy()
    rad[:, 3:] = np.radians(rad[:, 3:])  # radians written where degrees are expected
    assert "angle-units" in stewart(nominal, StewartData(rad, cal.legs))[1]


def test_stewart_validation_overlap_leg_range_and_outliers(cmm):
    nominal, _, cal, _ = cmm
    assert stewart(nominal, cal, validate=cal)[1] == ["validation-overlap"]
    legs = cal.legs.copy()
    legs[3, 2] += 2e-3  # one leg reading 2 mm off (noise 1 um)
    res, found = stewart(nominal, StewartData(cal.poses, legs))
    assert found == ["outliers"] and res.outliers == [3]
    lo = nominal.leg_range[0]
    narrow = type(nominal)(nominal.base_joints, nominal.platform_joints, nominal.probe_offset,
                           (lo, float(np.median(cal.legs))), nominal.leg_offsets, nominal.name)
    assert "leg-range" in stewart(narrow, cal)[1]


def test_stewart_rank_deficient_pose_set_is_unbounded(cmm):
    nominal, true, _, _ = cmm
    box = nominal.workspace_box().copy()
    box[3:, :] = 0.0  # no rotation at all: the platform only translates
    flat = simulate_stewart(true, 60, rng=3, box=box)
    res, found = stewart(nominal, flat)
    assert "rank-deficient" in found and not res.bounded
    assert not np.isfinite(res.std).all()
    assert any(p["std"] is None for p in res.to_dict()["parameters"].values())


def test_stewart_report_has_warnings_units_and_figure(cmm, tmp_path):
    nominal, _, cal, _ = cmm
    mm = cal.poses.copy()
    mm[:, :3] *= 1000.0
    res, _ = stewart(nominal, StewartData(mm, cal.legs * 1000.0))
    text = res.report(tmp_path / "r.html").read_text(encoding="utf-8")
    assert '<section id="warnings"' in text and "[scale-mismatch]" in text
    assert text.index('id="warnings"') < text.index('id="summary"')
    assert "rms [m]" in text and "data:image/png;base64," in text


# ------------------------------------------------------------------ hand-eye
def handeye(F, C, **kw):
    with diagnostics.collect() as found:
        res = calibrate_handeye(F, C, **kw)
    assert codes(res.warnings) == codes(found)
    return res, codes(found)


def parallel_axes(spread_deg, n, rng):
    """Camera poses whose rotations all turn about nearly the same axis."""
    ang = rng.uniform(-np.pi, np.pi, n)
    tilt = np.radians(spread_deg) * rng.normal(size=(n, 2))
    axes = np.column_stack([tilt, np.ones(n)])
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    return transform_from(matrix_from_axis_angle(axes * ang[:, None]),
                          rng.normal(size=(n, 3)) * 50.0 + [0.0, 0.0, 380.0])


def test_handeye_clean_schemes_and_real_recording_are_silent():
    rng = np.random.default_rng(0)
    for T in (star_polygon_poses(380.0, 60.0, 19), random_poses(380.0, 60.0, 19, rng),
              parallel_axes(30.0, 15, rng)):
        res, found = handeye(*_measure(T, rng))
        assert found == [], [d.message for d in res.warnings]
        assert res.x_uncertainty is not None and res.to_dict()["x_uncertainty"]["translation"] > 0
    from kinecal.cli.handeye import resolve_pairs
    from kinecal.io.handeye import read_handeye_pairs

    F, C = read_handeye_pairs(resolve_pairs("handeye-camodocal")[0])
    assert handeye(F, C, setup="eye-to-hand")[1] == []


def test_handeye_nearly_parallel_axes_warn_with_the_conditioning():
    rng = np.random.default_rng(1)
    G, C = _measure(parallel_axes(0.3, 15, rng), rng)
    res, found = handeye(G, C)
    assert found == ["handeye-conditioning"]
    unc = res.x_uncertainty
    assert unc.anisotropy > 10
    # the predicted uncertainty is honest: the actual error is of its size, not far below
    assert pose_error(res.X, X_TRUE)[1] < 5 * unc.translation


def test_handeye_duplicated_and_too_few_stations():
    rng = np.random.default_rng(2)
    G, C = _measure(random_poses(380.0, 60.0, 4, rng), rng)
    idx = [0, 0, 1, 1, 2, 2, 3, 3]
    assert handeye(G[idx], C[idx])[1] == ["duplicate-poses", "few-poses"]
    with diagnostics.collect(), pytest.raises(InputError, match="too-few-poses"):
        calibrate_handeye(G[[0, 0, 1, 1]], C[[0, 0, 1, 1]])


@pytest.mark.parametrize("make", ["random", "parallel"])
def test_handeye_target_in_metres_robot_in_millimetres(make):
    rng = np.random.default_rng(3)
    T = random_poses(380.0, 60.0, 19, rng) if make == "random" else parallel_axes(30.0, 15, rng)
    G, C = _measure(T, rng)
    C = C.copy()
    C[:, :3, 3] /= 1000.0
    res, found = handeye(G, C)
    assert "scale-mismatch" in found
    msg = next(d.message for d in res.warnings if d.code == "scale-mismatch")
    assert "robot poses in millimetres and target poses in metres" in msg, msg


def test_handeye_uncertainty_of_x_matches_monte_carlo():
    """The predicted RMS error of X against the actual one over noisy repeats (100-run
    study: translation 0.99-1.04, rotation 1.09-1.10; 40 runs here)."""
    rng = np.random.default_rng(4)
    star = star_polygon_poses(380.0, 60.0, 19)
    err, pred = [], []
    for _ in range(40):
        res = calibrate_handeye(*_measure(star, rng))
        err.append(pose_error(res.X, X_TRUE))
        pred.append((res.x_uncertainty.rotation_deg, res.x_uncertainty.translation))
    ratio = np.sqrt(np.mean(np.square(err), axis=0)) / np.mean(pred, axis=0)
    assert 0.75 <= ratio.min() and ratio.max() <= 1.35, ratio
