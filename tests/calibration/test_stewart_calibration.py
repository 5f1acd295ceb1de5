"""Geometry calibration of the parallel-link CMM (42 parameters, IK residual)."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal.calibration.stewart.calibrate import calibrate_stewart
from kinecal.calibration.stewart.data import (
    ARCSEC,
    StewartData,
    perturb_geometry,
    simulate_stewart,
)
from kinecal.calibration.stewart.identification import identifiability, identification_jacobian
from kinecal.calibration.stewart.result import pose_prediction_errors
from kinecal.errors import InputError
from kinecal.kinematics.stewart.platform import N_PARAMETERS, StewartPlatform


@pytest.fixture(scope="module")
def nominal() -> StewartPlatform:
    return StewartPlatform.liu2008()


@pytest.fixture(scope="module")
def truth(nominal) -> StewartPlatform:
    return perturb_geometry(nominal, 1e-3, rng=1)  # 1 mm geometry errors


def test_jacobian_matches_finite_differences(nominal, truth):
    poses = nominal.random_poses(8, rng=4)
    J = identification_jacobian(truth, poses)
    assert J.shape == (48, N_PARAMETERS)
    v, h = truth.parameters, 1e-6
    num = np.empty_like(J)
    for k in range(N_PARAMETERS):
        e = np.zeros(N_PARAMETERS)
        e[k] = h
        up = truth.with_parameters(v + e).inverse(poses)
        dn = truth.with_parameters(v - e).inverse(poses)
        num[:, k] = ((up - dn) / (2 * h)).ravel()
    np.testing.assert_allclose(J, num, rtol=0, atol=1e-8)


def test_all_42_parameters_identifiable(nominal):
    info = identifiability(nominal, nominal.random_poses(60, rng=0))
    assert info["rank"] == 42 and info["unidentifiable"] == []
    assert np.isfinite(info["condition_number"])
    # a single pose cannot identify 42 parameters: rank 6 (one equation per leg)
    assert identifiability(nominal, nominal.random_poses(1, rng=0))["rank"] == 6


def test_noise_free_recovery(nominal, truth):
    data = simulate_stewart(truth, 30, rng=2, position_noise=0, rotation_noise=0, leg_noise=0)
    res = calibrate_stewart(nominal, data)
    np.testing.assert_allclose(res.geometry.parameters, truth.parameters, rtol=0, atol=1e-10)
    assert res.calibration["after"]["rms"] < 1e-12


def test_noisy_calibration_meets_1um(nominal, truth):
    cal = simulate_stewart(truth, 60, rng=2, position_noise=1e-6, rotation_noise=ARCSEC)
    val = simulate_stewart(truth, 200, rng=3, position_noise=1e-6, rotation_noise=ARCSEC)
    res = calibrate_stewart(nominal, cal, validate=val)
    assert res.rank == 42
    assert res.validation["before"]["rms"] > 5e-4  # 1 mm errors: ~1.4 mm leg errors
    # leg-length prediction on the validation poses, against the noise-free readings
    pred = res.geometry.inverse(val.true_poses) - val.true_legs
    assert np.sqrt(np.mean(pred**2)) <= 1e-6
    # the residual on noisy data sits at the noise floor (legs 1 um + pose noise)
    assert res.validation["after"]["rms"] < 3e-6
    # pose prediction from the legs improves by three orders of magnitude
    before = pose_prediction_errors(nominal, val.true_legs, val.true_poses)
    after = pose_prediction_errors(res.geometry, val.true_legs, val.true_poses)
    assert before["position"]["rms"] > 1e-3
    assert after["position"]["rms"] < 3e-6
    assert after["rotation_arcsec"]["rms"] < 2.0
    # standard errors are consistent with the actual parameter errors
    z = (res.geometry.parameters - truth.parameters) / res.std
    assert np.sqrt(np.mean(z**2)) < 3.0
    d = res.to_dict()
    assert d["rank"] == 42 and len(d["parameters"]) == 42
    assert d["improvement_percent"] > 99.0


def test_simulation_reproducible(truth):
    a = simulate_stewart(truth, 10, rng=9)
    b = simulate_stewart(truth, 10, rng=9)
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.legs, b.legs)
    lo, hi = truth.leg_range
    assert (a.true_legs >= lo).all() and (a.true_legs <= hi).all()


def test_too_few_poses_and_bad_data(nominal, truth):
    data = simulate_stewart(truth, 6, rng=1)
    with pytest.raises(InputError, match=r"at least 8 distinct poses.*\[too-few-poses\]"):
        calibrate_stewart(nominal, data)
    poses = data.poses.copy()
    poses[3, 2] = np.nan
    with pytest.raises(InputError, match="row 4"):
        StewartData(poses, data.legs)
