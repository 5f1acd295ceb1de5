"""The instrument's stated noise (``calibrate(..., sigma=)``, ``--sigma``): the chi-square test
``residual-above-noise`` on data made to trigger it and on clean data that must not, and the
standard errors with the noise known (docs/diagnostics.md)."""

import dataclasses
import json

import numpy as np
import pytest

import kinecal
from kinecal import diagnostics
from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.error_model import calibrate_error_model
from kinecal.calibration.serial.simulate import simulate
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors import joint_errors_for

NOISE = 0.01


def run(model, data, **kw):
    with diagnostics.collect() as found:
        res = calibrate(model, data, **kw)
    return res, sorted({d.code for d in found})


@pytest.fixture(scope="module")
def irb():
    m = kinecal.load_model("irb120")
    return m, simulate(m, 60, noise=NOISE, rng=1)


def test_clean_data_pass_and_known_noise_standard_errors(irb):
    m, sim = irb
    res, found = run(m, sim.data, sigma=NOISE)
    assert found == []
    out = res.to_dict()
    noise = out["noise"]
    assert noise["verdict"] == "consistent" and noise["consistent"]
    # no orientations: 3 rows per pose less the rank of the fit
    assert noise["dof"] == 3 * 60 - res.identifiability.rank
    assert 0.8 < noise["ratio"] < 1.2 and noise["p_value"] > 1e-3
    assert noise["residual_sigma"] == pytest.approx(res.sigma, rel=1e-9)
    # known noise: the same (J^T W J)^+, scaled by S instead of the estimate
    factor = NOISE / res.sigma
    for name, std in noise["std"].items():
        assert std == pytest.approx(out["parameters"][name]["std"] * factor, rel=1e-9)
    pred, pred_known = out["predicted_error"], noise["predicted_error"]
    assert pred_known["calibration_mean"] == pytest.approx(pred["calibration_mean"] * factor)
    text = res.summary()
    assert "stated noise 0.01 mm per coordinate" in text and "consistent with it" in text
    assert "model uncertainty left with the stated noise" in text
    # without sigma nothing changes
    plain = calibrate(m, sim.data).to_dict()
    assert "noise" not in plain
    assert plain["parameters"] == out["parameters"]


def test_false_alarm_rate_and_chi_square_scale():
    """30 clean data sets (60 poses each): never a warning; chi2 / dof averages 1."""
    m = kinecal.load_model("irb120")
    ratios = []
    for seed in range(30):
        res, found = run(m, simulate(m, 30, noise=NOISE, rng=100 + seed).data, sigma=NOISE)
        assert found == [], seed
        ratios.append(res.extra["noise"]["chi2"] / res.extra["noise"]["dof"])
    # sd of chi2/dof per run ~ sqrt(2 / 67); of the mean of 30 runs ~0.03
    assert 0.88 < np.mean(ratios) < 1.12


@pytest.mark.parametrize("case", ["offset", "optimistic", "outlier"])
def test_residual_far_above_the_noise_is_warned(irb, case):
    m, sim = irb
    data, sigma = sim.data, NOISE
    if case == "offset":  # x + 5 mm: a missing base frame
        data = dataclasses.replace(data, xyz=data.xyz + [5.0, 0.0, 0.0])
    elif case == "optimistic":  # the instrument is twice as noisy as stated
        sigma = NOISE / 2
    else:
        xyz = data.xyz.copy()
        xyz[7, 2] += 2.0
        data = dataclasses.replace(data, xyz=xyz)
    res, found = run(m, data, sigma=sigma)
    assert "residual-above-noise" in found
    noise = res.to_dict()["noise"]
    assert noise["verdict"] == "above" and not noise["consistent"]
    assert noise["ratio"] > (100 if case == "offset" else 1.5)
    msg = next(d.message for d in res.warnings if d.code == "residual-above-noise")
    assert "--error-model auto" in msg and "stated noise is optimistic" in msg
    assert "ABOVE" in res.summary()


def test_pessimistic_noise_is_below_and_warned_beyond_twice(irb):
    m, sim = irb
    res, found = run(m, sim.data, sigma=1.5 * NOISE)  # below, but within a factor 2
    assert found == []
    assert res.extra["noise"]["verdict"] == "below"
    assert "looks pessimistic" in res.summary()
    for factor in (4, 1000):  # --sigma 10 where the residual is 0.01 mm (issue 28)
        res, found = run(m, sim.data, sigma=factor * NOISE)
        assert found == ["residual-below-noise"]
        assert res.extra["noise"]["verdict"] == "below"
        msg = res.warnings[0].message
        assert f"against {factor * NOISE:.3g} mm" in msg and "pessimistic" in msg


def test_orientation_rows_use_the_position_share_of_the_hat_matrix():
    m = kinecal.load_model("irb120")
    w = 300.0  # rotation_weight = S / angle noise: the rotation rows carry noise S too
    sim = simulate(m, 40, noise=NOISE, rng=5, orientation=True, angle_noise=NOISE / w)
    res, found = run(m, sim.data, sigma=NOISE, rotation_weight=w)
    assert found == []
    noise = res.extra["noise"]
    r = res.identifiability.rank
    assert 3 * 40 - r < noise["dof"] < 3 * 40  # the rotation rows take part of the rank
    assert noise["verdict"] == "consistent"


def test_joint_error_model_passes_sigma_and_reports_its_own_fit():
    """Harmonic errors: the geometric fit is far above the noise, the harmonic one is not
    (the geometric stage's finding is not reported for it)."""
    ur5 = kinecal.load_model("ur5")
    model = dataclasses.replace(ur5, joint_errors=joint_errors_for(ur5, ("harmonic",), 1))
    e = np.zeros(model.n_params)
    e[model.index(["dq2.sin1", "dq3.cos1"])] = [3e-4, -2e-4]
    sim = simulate(model, 120, errors=e, noise=NOISE, rng=8)
    _, geo_found = run(ur5, sim.data, sigma=NOISE)
    assert "residual-above-noise" in geo_found
    with diagnostics.collect() as found:
        res = calibrate_error_model(ur5, sim.data, "harmonic", harmonics=1, sigma=NOISE)
    assert "residual-above-noise" not in {d.code for d in found}
    assert res.to_dict()["noise"]["verdict"] == "consistent"


def test_bad_sigma_is_refused_before_any_work(irb):
    m, sim = irb
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(InputError, match="--sigma"):
            calibrate(m, sim.data, sigma=bad)
    with pytest.raises(InputError, match="larger than the whole machine"):
        calibrate(m, sim.data, sigma=1e300)


def test_cli_sigma(tmp_path, capsys):
    data = tmp_path / "meas.csv"
    assert main(["simulate", "irb120", "--poses", "40", "--noise", "0.01", "--seed", "2",
                 "--out", str(data), "--quiet"]) == 0
    out = tmp_path / "r.json"
    report = tmp_path / "r.html"
    assert main(["calibrate", "irb120", str(data), "--sigma", "0.01", "--out", str(out),
                 "--report", str(report), "--quiet"]) == 0
    assert "stated noise 0.01 mm per coordinate" in report.read_text()
    noise = json.loads(out.read_text())["noise"]
    assert noise["verdict"] == "consistent" and set(noise["predicted_error"]) >= {
        "calibration_mean", "validation_mean"}
    capsys.readouterr()
    assert main(["calibrate", "irb120", str(data), "--sigma", "0.002", "--strict",
                 "--out", str(tmp_path / "s.json")]) == 2
    assert "[residual-above-noise]" in capsys.readouterr().err
    assert not (tmp_path / "s.json").exists()
    assert main(["calibrate", "irb120", str(data), "--sigma", "2000"]) == 2
    err = capsys.readouterr().err
    assert "option --sigma" in err and "larger than the whole machine" in err
    assert main(["calibrate", "irb120", str(data), "--sigma", "0"]) == 2
