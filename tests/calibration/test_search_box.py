"""The metaheuristics' search box (`kinecal.calibration.serial.box`): derived from the data by
default, the model file's tolerances on request, and ``at-bounds`` when the answer sits on
its face."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import kinecal
from kinecal import diagnostics
from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.box import AT_BOUNDS, SE_WIDTH, check_at_bounds, search_box
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.calibration.serial.simulate import simulate
from kinecal.cli import main
from kinecal.errors import InputError


@pytest.fixture(scope="module")
def beyond():
    """An IRB-120 whose alpha2 error is three times its tolerance (the minimum lies outside
    the tolerance box around nominal), measured at 60 poses with 10 um noise."""
    m = kinecal.load_model("irb120")
    err = np.zeros(m.n_params)
    i = m.index(["alpha2"])[0]
    err[i] = 3.0 * m.tolerances["angle"]  # rad
    err[m.index(["a2", "d4"])] = [0.1, -0.1]
    cal = simulate(m, 60, errors=err, noise=0.01, rng=3)
    val = simulate(m, 100, errors=err, noise=0.0, rng=4)
    return m, cal.data, val.data, cal.true_params


def _codes(res):
    return [w.code for w in res.warnings]


def test_the_tolerance_box_stops_on_its_face_and_says_so(beyond):
    m, cal, val, _ = beyond
    lm = calibrate(m, cal, validate=val)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate(m, cal, "pso", validate=val, rng=0, maxiter=150,
                        options={"box": "tolerances"})
    assert "at-bounds" in _codes(res)
    msg = next(w.message for w in res.warnings if w.code == "at-bounds")
    assert "alpha2 (upper face)" in msg and "tolerance box" in msg
    box = res.extra["search_box"]
    assert box["box"] == "tolerances"
    assert res.params[m.index(["alpha2"])[0]] == pytest.approx(box["upper"]["alpha2"])
    # the face holds it away from the data's minimum
    assert res.val_after.mean() > 5 * lm.val_after.mean()


def test_the_data_box_holds_the_minimum(beyond):
    m, cal, val, truth = beyond
    lm = calibrate(m, cal, validate=val)
    res = calibrate(m, cal, "de", validate=val, rng=0, maxiter=150)
    assert "at-bounds" not in _codes(res) and "optimizer-stalled" not in _codes(res)
    # the default box is centred on the LM fit: DE's cost (the mean distance error) ends
    # at or below LM's there, and the held-out error at LM's noise level (34 mm before)
    assert res.errors_after.mean() <= lm.errors_after.mean()
    assert res.val_after.mean() < 1.2 * lm.val_after.mean() < 0.01
    box = res.extra["search_box"]
    assert box["box"] == "data"
    lo = np.array([box["lower"][n] for n in res.free])
    hi = np.array([box["upper"][n] for n in res.free])
    x_lm = lm.params[m.index(res.free)]
    np.testing.assert_allclose((lo + hi) / 2, x_lm, rtol=0, atol=1e-9)
    # half-widths: SE_WIDTH standard errors of the LM fit, within [FLOOR, 1] x tolerance
    half = (hi - lo) / 2
    np.testing.assert_allclose(half, np.clip(SE_WIDTH * lm.std[m.index(res.free)],
                                             1e-3 * _tolerance(m, res.free),
                                             _tolerance(m, res.free)), rtol=1e-6)
    # the true alpha2 lies inside the data box, outside the tolerance box
    i = res.free.index("alpha2")
    j = m.index(["alpha2"])[0]
    assert lo[i] < truth[j] < hi[i]
    assert truth[j] - m.nominal[j] > _tolerance(m, ["alpha2"])[0]


def _tolerance(m, names):
    angle = m.is_angle()[m.index(names)]
    return np.where(angle, m.tolerances["angle"], m.tolerances["length"])


def test_same_seed_same_answer_in_the_data_box(beyond):
    m, cal, _, _ = beyond
    a = calibrate(m, cal, "de", rng=5, maxiter=40)
    b = calibrate(m, cal, "de", rng=5, maxiter=40)
    assert np.array_equal(a.params, b.params)


def test_at_bounds_names_the_parameters_on_a_face(beyond):
    m, cal, _, _ = beyond
    pr = CalibrationProblem(m, cal, ["a2", "alpha2", "d4"])
    bounds = np.array([[0.0, 1.0], [-1.0, 1.0], [2.0, 4.0]])
    inside = np.array([0.5, 0.0, 3.0])
    with diagnostics.collect() as found:
        box = {"box": "data", "lower": bounds[:, 0], "upper": bounds[:, 1]}
        assert check_at_bounds(pr, inside, box, "pso") == []
        on = inside + [0.5 - 0.5 * AT_BOUNDS, 0.0, -1.0]  # a2 within 0.1 %, d4 exactly
        assert check_at_bounds(pr, on, box, "pso") == ["a2", "d4"]
    assert [d.code for d in found] == ["at-bounds"]
    assert "a2 (upper face), d4 (lower face)" in found[0].message
    assert "stalled on its face" in found[0].message


def test_search_box_tolerances_is_the_model_files(beyond):
    m, cal, _, _ = beyond
    pr = CalibrationProblem(m, cal, ["a2", "alpha2"])
    bounds, info = search_box(pr, "tolerances")
    np.testing.assert_array_equal(bounds, pr.bounds())
    assert info["box"] == "tolerances"


def test_box_option_is_checked(beyond):
    m, cal, _, _ = beyond
    with pytest.raises(InputError, match="box: expected one of data, tolerances"):
        calibrate(m, cal, "pso", maxiter=2, options={"box": "wide"})
    with pytest.raises(InputError, match="a hybrid searches a box shrunk"):
        calibrate(m, cal, "hybrid-pso", maxiter=2, options={"box": "data"})


def test_cli_box(tmp_path, capsys):
    meas = tmp_path / "meas.csv"
    assert main(["simulate", "irb120", "--poses", "40", "--noise", "0.01", "--seed", "1",
                 "--out", str(meas), "--quiet"]) == 0
    assert main(["calibrate", "irb120", str(meas), "--box", "tolerances"]) == 2
    assert "--box" in capsys.readouterr().err
    out = tmp_path / "r.json"
    assert main(["calibrate", "irb120", str(meas), "--method", "de", "--maxiter", "20",
                 "--seed", "0", "--box", "tolerances", "--out", str(out), "--quiet"]) == 0
    assert json.loads(out.read_text())["search_box"]["box"] == "tolerances"
