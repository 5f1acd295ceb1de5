"""Plausibility diagnostics of serial calibrations: each on data made to trigger it and on
clean data that must stay silent (docs/diagnostics.md)."""

import warnings

import numpy as np
import pytest

import kinecal
from kinecal import diagnostics
from kinecal.calibration.diagnostics import CODES
from kinecal.calibration.diagnostics._common import (
    chi3_outliers,
    repeat_groups,
    rigid_rms,
    similarity_fit,
)
from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.simulate import simulate
from kinecal.data import Measurements
from kinecal.diagnostics import KinecalWarning
from kinecal.errors import InputError

SERIAL_MODELS = ["irb120", "ur5", "kr6-craig", "puma560", "hu2005-scanner"]


def codes(found):
    return sorted({d.code for d in found})


def run(model, data, **kw):
    """Calibrate inside a collector; returns (result, codes)."""
    with diagnostics.collect() as found:
        res = calibrate(model, data, **kw)
    assert codes(res.warnings) == codes(found)
    return res, codes(found)


@pytest.fixture(scope="module")
def irb():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 50, errors="random", noise=0.01, rng=1)
    val = simulate(m, 40, errors=sim.true_params - m.nominal, noise=0.01, rng=2)
    return m, sim, val


# ------------------------------------------------------------------ clean data is silent
@pytest.mark.parametrize("name", SERIAL_MODELS)
def test_clean_simulated_data_of_every_bundled_model_is_silent(name):
    m = kinecal.load_model(name)
    for seed in (3, 4):
        sim = simulate(m, 60, errors="random", noise=0.01, rng=seed)
        val = simulate(m, 30, errors=sim.true_params - m.nominal, noise=0.01, rng=seed + 10)
        res, found = run(m, sim.data, validate=val.data)
        assert found == [], (name, seed, [d.message for d in res.warnings])
        assert res.bounded and np.isfinite(res.std).all()


def test_clean_orientation_data_and_robust_loss_are_silent():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 40, errors="random", noise=0.01, rng=5, orientation=True,
                   angle_noise=1e-4)
    assert run(m, sim.data)[1] == []
    assert run(m, sim.data, loss="soft_l1")[1] == []


def test_bundled_ur5_laser_tracker_data_is_silent():
    m = kinecal.load_model("ur5")
    grid = kinecal.read_measurements("ur5-laser-tracker:grid", m)
    val = kinecal.read_measurements("ur5-laser-tracker:random", m)
    res, found = run(m, grid, validate=val)
    assert found == [] and res.to_dict()["warnings"] == []


def test_python_api_issues_kinecal_warnings_and_cli_scope_does_not(irb):
    m, sim, _ = irb
    bad = Measurements(sim.data.q, sim.data.xyz / 1000.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = calibrate(m, bad)
        assert any(issubclass(w.category, KinecalWarning) and "[scale-mismatch]" in
                   str(w.message) for w in caught)
        caught.clear()
        with diagnostics.collect() as outer:  # the command line's collector
            calibrate(m, bad)
        assert not caught and "scale-mismatch" in codes(outer)
    assert "scale-mismatch" in codes(res.warnings)
    assert res.to_dict()["warnings"][0]["code"] == res.warnings[0].code
    with diagnostics.strict(), pytest.raises(InputError, match=r"\[scale-mismatch\]"):
        calibrate(m, bad)


# ------------------------------------------------------------------ pose counts
def test_too_few_distinct_poses_are_refused(irb):
    m, sim, _ = irb
    one = Measurements(sim.data.q[[0, 0, 0]], sim.data.xyz[[0, 0, 0]])
    # one pose identifies only 3 parameters: the advice counts what well-spread poses
    # identify (20 for the IRB-120), not the 3 the single pose determines
    with diagnostics.collect(), pytest.raises(InputError, match=r"well-spread poses identify "
                                              r"20 parameters: measure at least 7 distinct"):
        calibrate(m, one)
    seven = sim.data.subset(np.arange(7))  # 21 equations for the identifiable parameters
    with diagnostics.collect(), pytest.raises(InputError, match=r"too-few-poses"):
        calibrate(m, seven, free="all")


def test_few_poses_warn_below_three_equations_per_parameter(irb):
    m, sim, _ = irb
    assert "few-poses" in run(m, sim.data.subset(np.arange(14)))[1]
    assert "few-poses" not in run(m, sim.data.subset(np.arange(30)))[1]


def test_duplicated_rows_warn_and_do_not_shrink_the_standard_errors(irb):
    m, sim, _ = irb
    ref, found = run(m, sim.data)
    assert found == []
    idx = np.repeat(np.arange(len(sim.data)), 10)
    dup, found = run(m, sim.data.subset(idx))
    assert "duplicate-poses" in found
    free = m.index(dup.free)
    np.testing.assert_allclose(dup.std[free], ref.std[free], rtol=1e-6)
    assert dup.to_dict()["independent_poses"] == len(sim.data)
    np.testing.assert_allclose(dup.predicted_error_summary()["calibration_mean"],
                               ref.predicted_error_summary()["calibration_mean"], rtol=1e-6)


def test_repeated_measurements_give_a_lack_of_fit_test(irb):
    m, sim, _ = irb
    rng = np.random.default_rng(0)
    q = np.repeat(sim.data.q, 3, axis=0)
    exact = np.repeat(sim.exact_xyz, 3, axis=0)
    fine = exact + rng.normal(0, 0.01, exact.shape)  # repeatability = the noise: silent
    assert run(m, Measurements(q, fine))[1] == ["duplicate-poses"]
    # a systematic error the model cannot take (a joint-2 dependent bulge) far above it
    bulge = fine + 0.3 * np.sin(3 * q[:, [1]]) * [[0, 0, 1]]
    assert "lack-of-fit" in run(m, Measurements(q, bulge))[1]


# ------------------------------------------------------------------ units and frames
def test_metres_in_a_millimetre_model(irb):
    m, sim, _ = irb
    res, found = run(m, Measurements(sim.data.q, sim.data.xyz / 1000.0))
    assert "scale-mismatch" in found
    assert "metres in a millimetre model" in res.warnings[0].message


def test_millimetres_in_a_metre_model(irb):
    # the residual of the similarity fit is in the measured unit: a true arm a few tenths of
    # a millimetre off nominal, read 1000 times too large, must still show the scale
    m, sim, _ = irb
    res, found = run(m, Measurements(sim.data.q, sim.data.xyz * 1000.0))
    assert "scale-mismatch" in found
    assert "millimetres in a metre model" in res.warnings[0].message


def test_radians_in_a_degree_model(irb):
    m, sim, _ = irb
    as_rad = Measurements(sim.data.q * np.pi / 180.0, sim.data.xyz)  # radians read as degrees
    assert "joint-units" in run(m, as_rad)[1]


def test_degrees_in_a_radian_model():
    m = kinecal.load_model("irb120")
    rad = m.with_params(m.nominal)
    rad.angle_unit = "rad"
    sim = simulate(rad, 50, errors="random", noise=0.01, rng=1)
    # degree values read as radians: far outside the limits, and the fit is far better in deg
    as_deg = Measurements(np.degrees(sim.data.q), sim.data.xyz)
    found = run(rad, as_deg)[1]
    assert "joint-units" in found and "joint-limits" in found


def test_negated_axis_is_a_mirrored_frame(irb):
    m, sim, _ = irb
    assert "mirrored-frame" in run(m, Measurements(sim.data.q, sim.data.xyz * [1, 1, -1]))[1]


def test_data_of_another_robot(irb):
    m = irb[0]
    ur5 = kinecal.read_measurements("ur5-laser-tracker:random", m)  # UR5 poses for an IRB-120
    found = run(m, ur5)[1]
    assert "initial-error" in found and "joint-limits" in found


def test_joint_readings_outside_the_limits(irb):
    m, sim, _ = irb
    q = sim.data.q.copy()
    q[:5, 2] = np.radians(100.0)  # q3 limits are [-110, 70] deg
    sim2 = simulate(m, 0, errors=sim.true_params - m.nominal, noise=0.01, q=q, rng=3)
    res, found = run(m, sim2.data)
    assert found == ["joint-limits"] and "q3" in res.warnings[0].message


def test_validation_rows_that_repeat_calibration_rows(irb):
    m, sim, val = irb
    assert run(m, sim.data, validate=sim.data)[1] == ["validation-overlap"]
    assert run(m, sim.data, validate=val.data)[1] == []


# ------------------------------------------------------------------ rank and uncertainty
def test_one_joint_moved_is_rank_deficient_and_unbounded(irb):
    m, sim, _ = irb
    q = np.repeat(sim.data.q[:1], 40, axis=0)
    q[:, 0] = np.linspace(-2.5, 2.5, 40)
    one = simulate(m, 0, errors=sim.true_params - m.nominal, noise=0.01, q=q, rng=4)
    res, found = run(m, one.data)
    assert "rank-deficient" in found
    assert not res.bounded and len(res.lost) >= 15
    pred = res.to_dict()["predicted_error"]
    assert pred["calibration_mean"] is None and pred["bounded"] is False
    assert "not bounded" in res.summary()


def test_free_all_reports_confounded_parameters_as_not_identifiable(irb):
    m, sim, _ = irb
    res, found = run(m, sim.data, free="all")
    assert found == ["unidentifiable-free"]
    d = res.to_dict()
    loose = res.unidentifiable_free()
    assert {"d3", "alpha6"} <= set(loose) and set(loose) == set(d["unidentifiable"])
    for name, entry in d["parameters"].items():
        assert (entry["std"] is None) == (name in loose), name
        if entry["std"] is not None:
            assert entry["std"] > 0 or not entry["free"]
    text = res.summary()
    assert "not identifiable (free, value arbitrary" in text and "held at nominal" not in text
    assert all(n in text for n in loose)
    # positions stay bounded: the confounding is the same at every pose
    assert np.isfinite(d["predicted_error"]["calibration_mean"])


def test_free_list_of_a_confounded_pair(irb):
    m, sim, _ = irb
    res, found = run(m, sim.data, free=["d2", "d3"])
    assert "unidentifiable-free" in found
    assert np.isinf(res.std[m.index(["d2", "d3"])]).all()
    assert res.to_dict()["parameters"]["d3"]["std"] is None


# ------------------------------------------------------------------ after the fit
def test_outlier_with_the_default_loss(irb):
    m, sim, _ = irb
    xyz = sim.data.xyz.copy()
    xyz[5, 2] += 50.0
    res, found = run(m, Measurements(sim.data.q, xyz))
    assert "outliers" in found and res.outliers == [5]
    # the 50 mm pull turns the wrist (alpha5 -169 deg): another arm by the same-arm rule
    # of fk --params and export, which the calibration says too
    from kinecal.kinematics.serial.same_arm import compare_arms

    assert set(found) - {"outliers"} == ({"implausible-change"} if not compare_arms(
        res.nominal_model, res.model).same else set())
    robust, found = run(m, Measurements(sim.data.q, xyz), loss="soft_l1")
    assert robust.outliers == [5] and found == []


def test_constant_offset_asks_for_a_base_frame(irb):
    m, sim, _ = irb
    res, found = run(m, Measurements(sim.data.q, sim.data.xyz + [5.0, 0, 0]))
    assert "residual-offset" in found
    msg = next(d.message for d in res.warnings if d.code == "residual-offset")
    assert "base.x +5 mm" in msg


def test_parameter_far_beyond_its_tolerance():
    m = kinecal.load_model("irb120")
    e = np.zeros(m.n_params)
    e[m.index(["a2"])] = 5.0  # 20 tolerances of 0.25 mm
    sim = simulate(m, 50, errors=e, noise=0.01, rng=6)
    assert run(m, sim.data)[1] == ["parameter-tolerance"]


def test_tool_points_far_from_nominal_are_set_up_not_geometry():
    """Where the reflectors sit on the flange is the measurement set-up, like the base
    frame: three markers that all start at the model's tool point (a URDF, a file's
    `marker` names) must not read as "probably the wrong model"."""
    m = kinecal.load_model("puma560").with_markers({"A": [0, 0, 50], "B": [0, 0, 50],
                                                    "C": [0, 0, 50]})
    e = np.zeros(m.n_params)
    e[m.index(["tool.A.x", "tool.B.y", "tool.C.x", "tool.C.z"])] = [30.0, -25.0, -20.0, 15.0]
    e[m.index(["a2"])] = 0.3
    sim = simulate(m, 40, errors=e, noise=0.01, rng=7)
    res, found = run(m, sim.data)
    assert found == []
    # (tool.A.x trades with a6 here: the joint geometry stands in for the marker)
    assert res.errors_after.mean() < 0.03


def test_codes_are_documented():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "diagnostics.md").read_text()
    for code in CODES:
        assert f"`{code}`" in doc, code


# ------------------------------------------------------------------ helpers
def test_helpers_on_known_answers():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(30, 3))
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    R *= np.sign(np.linalg.det(R))
    B = A @ R.T + [1.0, 2.0, 3.0]
    assert rigid_rms(A, B) < 1e-12
    assert rigid_rms(A, B * [1, 1, -1]) > 0.5 > rigid_rms(A, B * [1, 1, -1], reflection=True)
    s, e = similarity_fit(A, 1e-3 * B)
    assert s == pytest.approx(1e-3) and e < 1e-8
    g, n = repeat_groups(np.array([[1.0, 2.0], [3.0, 4.0], [1.0, 2.0 + 1e-9]]))
    assert n == 2 and list(g) == [0, 1, 0]
    d = np.linalg.norm(rng.normal(size=(200, 3)), axis=1)  # Gaussian noise: no outlier
    assert chi3_outliers(d) == []
    d[17] = 20.0
    assert chi3_outliers(d) == [17]


def test_simulate_with_absolute_values_instead_of_deviations():
    m = kinecal.load_model("irb120")
    sim = simulate(m, 5, errors="random", rng=0)
    with diagnostics.collect() as found:
        simulate(m, 5, errors=sim.true_params - m.nominal, rng=0)  # deviations: fine
        assert found == []
        simulate(m, 5, errors=sim.true_params, rng=0)  # absolute values by mistake
    assert codes(found) == ["absolute-errors"]
    assert "true_params - model.nominal" in found[0].message
