"""`kinecal.load_result` (serial, hand-eye, Stewart result files back into objects), the API
entry points taking paths, and the short reprs of results."""

from __future__ import annotations

import json

import numpy as np
import pytest

import kinecal
from kinecal.cli import main
from kinecal.datasets import dataset_dir
from kinecal.errors import InputError


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """A calibration of the IRB-120 (60 simulated poses), its result file and data."""
    folder = tmp_path_factory.mktemp("serial")
    model = kinecal.load_model("irb120")
    sim = kinecal.simulate(model, 60, noise=0.01, rng=3)
    val = kinecal.simulate(model, 20, errors=sim.true_params - model.nominal, noise=0.01,
                           rng=4)
    from kinecal.io.measurements import write_measurements

    write_measurements(folder / "meas.csv", sim.data, model)
    write_measurements(folder / "val.csv", val.data, model)
    res = kinecal.calibrate(model, sim.data, validate=val.data)
    res.to_json(folder / "result.json")
    return folder, model, res


def _program(model):
    """Joints well inside the limits (half the random range): every row compensates."""
    return kinecal.simulate(model, 5, rng=7).data.q * 0.5


def test_serial_result_round_trip_and_uses(serial):
    folder, model, res = serial
    loaded = kinecal.load_result(folder / "result.json")
    assert type(loaded).__name__ == "SerialResultFile"
    # the identified values, degrees back to radians: the same vector to round-off
    np.testing.assert_allclose(loaded.params, res.params, rtol=0, atol=1e-12)
    assert loaded.free == res.free
    finite = np.isfinite(res.std)
    np.testing.assert_allclose(loaded.std[finite], res.std[finite], rtol=1e-12, atol=1e-15)
    q = res.q_validation
    np.testing.assert_allclose(loaded.model.positions(q), res.model.positions(q), atol=1e-9)
    # usable where a fresh result is: compensation gives the same joints
    a = kinecal.compensate(res, joints=_program(model))
    b = kinecal.compensate(loaded, joints=_program(model))
    assert a.converged.all()
    np.testing.assert_allclose(b.q, a.q, atol=1e-10)
    # and the model file it writes is the calibrated model
    loaded.save_model(folder / "cal.yaml")
    again = kinecal.load_model(folder / "cal.yaml")
    np.testing.assert_allclose(again.positions(q), res.model.positions(q), atol=1e-9)


def test_serial_result_needs_its_model(serial, tmp_path):
    folder, model, _ = serial
    data = json.loads((folder / "result.json").read_text())
    data["model"] = "my-arm"
    other = tmp_path / "r.json"
    other.write_text(json.dumps(data))
    with pytest.raises(InputError, match="not a bundled one: give model="):
        kinecal.load_result(other)
    assert kinecal.load_result(other, model=model).params.shape == (model.n_params,)
    with pytest.raises(InputError, match="a result of another model"):
        kinecal.load_result(folder / "result.json", model="ur5")
    with pytest.raises(TypeError, match="model: expected a SerialModel"):
        kinecal.load_result(other, model=3)


def test_handeye_and_stewart_results(tmp_path, capsys):
    he = tmp_path / "he.json"
    assert main(["handeye", "handeye-tabb1", "--out", str(he), "--quiet"]) == 0
    loaded = kinecal.load_result(he)
    assert type(loaded).__name__ == "HandEyeResultFile"
    data = json.loads(he.read_text())
    np.testing.assert_array_equal(loaded.X, np.asarray(data["X"]))
    assert loaded.setup == "eye-in-hand" and loaded.length_unit == "mm"
    assert "\n" not in repr(loaded) and "HandEyeResultFile" in repr(loaded)

    data_csv, st = tmp_path / "data.csv", tmp_path / "st.json"
    geom_out = tmp_path / "cal.yaml"
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "30", "--seed", "1",
                 "--out", str(data_csv), "--quiet"]) == 0
    assert main(["stewart", "calibrate", "liu2008-cmm", str(data_csv), "--out", str(st),
                 "--geometry-out", str(geom_out), "--quiet"]) == 0
    capsys.readouterr()
    loaded = kinecal.load_result(st)
    assert type(loaded).__name__ == "StewartResultFile"
    written = kinecal.load_geometry(geom_out)
    np.testing.assert_allclose(loaded.geometry.parameters, written.parameters, atol=1e-12)
    poses = np.array([[0.04, 0.09, 0.92, 0.1, -0.05, 0.2]])
    np.testing.assert_allclose(loaded.geometry.inverse(poses), written.inverse(poses),
                               atol=1e-12)


def test_a_result_of_another_kind_is_named(tmp_path):
    with pytest.raises(InputError, match="a hand-eye calibration result"):
        from kinecal.io.result_values import parameters_from_result

        path = tmp_path / "x.json"
        path.write_text(json.dumps({"X": np.eye(4).tolist()}))
        parameters_from_result(kinecal.load_model("ur5"), path)


def test_entry_points_take_paths_and_name_the_type(serial):
    folder, model, res = serial
    by_path = kinecal.calibrate("irb120", str(folder / "meas.csv"),
                                validate=folder / "val.csv")
    # the file holds the joints in degrees (round trip: 1e-16 relative, the fit 1e-11)
    np.testing.assert_allclose(by_path.params, res.params, rtol=0, atol=1e-8)
    assert kinecal.simulate("irb120", 4, rng=1).data.q.shape == (4, 6)
    m = kinecal.read_measurements(folder / "meas.csv", "irb120")
    assert len(m) == 60
    c = kinecal.compensate(str(folder / "result.json"), joints=_program(model))
    assert c.converged.all()
    with pytest.raises(TypeError, match="data: expected Measurements"):
        kinecal.calibrate(model, 5)
    with pytest.raises(TypeError, match="model: expected a SerialModel"):
        kinecal.simulate(3, 10)
    with pytest.raises(TypeError, match="program joints: expected an array"):
        kinecal.compensate(res, joints="program.csv")
    with pytest.raises(TypeError, match="flange2base: expected an array"):
        kinecal.calibrate_handeye(str(dataset_dir("handeye-tabb1") / "pairs.csv"), None)
    with pytest.raises(TypeError, match="data: expected Measurements"):
        kinecal.calibrate_error_model(model, {"q": 1})


def test_reprs_are_one_short_line(serial):
    folder, model, res = serial
    sim = kinecal.simulate(model, 5, rng=0)
    comp = kinecal.compensate(res, joints=_program(model))
    geom = kinecal.load_geometry("liu2008-cmm")
    objects = [model, res, res.identifiability, sim, sim.data, comp, comp.ik, geom,
               geom.forward(np.array([0.75, 0.78, 0.8, 0.9, 0.87, 0.85])),
               kinecal.load_result(folder / "result.json")]
    for obj in objects:
        text = repr(obj)
        assert text.startswith(f"<{type(obj).__name__} ") and text.endswith(">"), text
        assert "\n" not in text and len(text) < 200, text
        assert "array(" not in text and "[[" not in text, text
    assert f"{res.validation_stats['after']['mean']:.4g} mm" in repr(res)
