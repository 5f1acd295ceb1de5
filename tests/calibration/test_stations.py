"""Several tracker set-ups (stations) solved in one problem, validation data from a moved
tracker re-registered (``--validate-register``) or warned about (``validation-frame``), and
rows weighted by their per-axis standard deviations."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from scipy.optimize import least_squares

import kinecal
from kinecal.calibration.blocks.stations import StationBlock
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.calibration.serial.row_weights import sigma_row_scale
from kinecal.cli import main
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.io.measurements import write_measurements
from kinecal.spatial import (
    axis_angle_from_matrix,
    matrix_from_axis_angle,
    transform_from_xyz_rpy,
    xyz_rpy_from_transform,
)

#: two set-ups: one at pitch 90 deg (roll-pitch-yaw's gimbal lock), one turned upside down
STATIONS = (transform_from_xyz_rpy([1500.0, -300.0, 200.0, 0.1, np.pi / 2, -0.4]),
            transform_from_xyz_rpy([-800.0, 2500.0, -100.0, 2.5, -0.3, 1.2]))


def _truth(n=120, orientation=True, rng=1):
    """The IRB-120 with errors on what stations can see (not theta1, d1: they move the
    whole arm, as the stations do; nor d2, one with d3), measured from the two `STATIONS`
    in turn."""
    model = kinecal.load_model("irb120")
    gen = np.random.default_rng(0)
    names = [p for p in model.calibratable if p not in ("theta1", "d1", "d2")]
    angle = model.is_angle()
    err = {p: gen.uniform(-2e-3, 2e-3) if angle[model.index([p])[0]] else gen.uniform(-0.3, 0.3)
           for p in names}
    sim = kinecal.simulate(model, n, errors=err, rng=rng, orientation=orientation)
    st = np.arange(n) % 2
    T = np.einsum("nij,njk->nik", np.stack([STATIONS[s] for s in st]),
                  model.fk(sim.data.q, sim.true_params))
    data = Measurements(sim.data.q, T[:, :3, 3], rotations=T[:, :3, :3] if orientation
                        else None, station=st, station_names=("A", "B"))
    return model, sim, data


@pytest.mark.parametrize("orientation", [True, False])
def test_two_stations_are_recovered_to_truth(orientation):
    model, sim, data = _truth(orientation=orientation)
    res = kinecal.calibrate(model, data)
    assert res.errors_after.max() < 1e-7
    ident = [p for p in res.free]
    idx = model.index(ident)
    np.testing.assert_allclose(res.params[idx], sim.true_params[idx], atol=1e-7)
    (entry,) = res.extra["kinds"]
    poses = {u["station"]: transform_from_xyz_rpy(u["pose"]) for u in entry["unknowns"]}
    for name, S in zip(("A", "B"), STATIONS, strict=True):
        np.testing.assert_allclose(poses[name], S, atol=1e-7)
    # the mix cannot see where the arm stands: its own base and theta1, d1 are held
    assert "theta1" not in res.free and "d1" not in res.free
    frames = res.to_dict()["frames"]["stations"]
    assert set(frames) == {"A", "B"} and set(frames["A"]["parameters"]) == {
        f"base@A.{k}" for k in ("x", "y", "z", "rx", "ry", "rz")}


def test_station_per_file_on_the_command_line(tmp_path, capsys):
    model, _, data = _truth(orientation=False)
    files = []
    for s, name in enumerate(("left", "right")):
        rows = np.flatnonzero(data.station == s)
        plain = dataclasses.replace(data.subset(rows), station=None, station_names=())
        write_measurements(tmp_path / f"{name}.csv", plain, model)
        files.append(str(tmp_path / f"{name}.csv"))
    out = tmp_path / "r.json"
    assert main(["calibrate", "irb120", *files, "--station-per-file", "--out", str(out),
                 "--quiet"]) == 0
    frames = json.loads(out.read_text())["frames"]["stations"]
    for name, S in zip(("left", "right"), STATIONS, strict=True):
        got = transform_from_xyz_rpy(np.r_[frames[name]["calibrated"][:3],
                                           np.radians(frames[name]["calibrated"][3:])])
        np.testing.assert_allclose(got, S, atol=1e-6)
    # one station named twice is refused, so is a station column with --station-per-file
    with pytest.raises(InputError, match="station left appears in"):
        kinecal.calibrate(model, [dataclasses.replace(
            data, station=np.zeros(len(data), np.intp), station_names=("left",))] * 2)
    write_measurements(tmp_path / "both.csv", data, model)
    assert main(["calibrate", "irb120", str(tmp_path / "both.csv"), "--station-per-file"]) == 2
    assert "station column" in capsys.readouterr().err


def _moved(model, sim, n=60, rng=7):
    """Validation rows of the same true arm measured after the tracker moved 2 m and
    turned 40 deg, with the tool remounted 0.5 mm off."""
    val = kinecal.simulate(model, n, errors=sim.true_params - model.nominal, rng=rng,
                           noise=0.01)
    p = sim.true_params.copy()
    p[model.index(["tool.x", "tool.y"])] += [0.5, -0.3]
    X = transform_from_xyz_rpy([2000.0, -1000.0, 300.0, 0.2, -0.3, 0.7])
    P = model.positions(val.data.q, p) @ X[:3, :3].T + X[:3, 3]
    P += np.random.default_rng(rng).normal(0, 0.01, P.shape)
    return Measurements(val.data.q, P, source="moved.csv")


def test_validate_register_recovers_a_moved_tracker():
    model = kinecal.load_model("irb120")
    sim = kinecal.simulate(model, 80, noise=0.01, rng=3)
    moved = _moved(model, sim)
    # judged as it is: metres of error, and the warning says why
    raw = kinecal.calibrate(model, sim.data, validate=moved)
    assert raw.val_after.mean() > 100
    assert [w.code for w in raw.warnings].count("validation-frame") == 1
    # re-registered on all rows: the model's accuracy, as if measured in its own frame
    res = kinecal.calibrate(model, sim.data, validate=moved, validate_register="all")
    assert "validation-frame" not in [w.code for w in res.warnings]
    assert res.val_after.mean() < 0.03 and res.val_before.mean() > 0.3
    reg = res.to_dict()["validation_register"]
    assert reg["fit_rows"] == reg["judged_rows"] == 60
    base = np.r_[reg["frames"][0][:3], np.radians(reg["frames"][0][3:])]
    X = transform_from_xyz_rpy([2000.0, -1000.0, 300.0, 0.2, -0.3, 0.7])
    assert np.linalg.norm(transform_from_xyz_rpy(base)[:3, 3] - X[:3, 3]) < 0.5
    # on 25 % of the rows, judged on the other 45: drawn by the seed, the same for the same
    part = kinecal.calibrate(model, sim.data, validate=moved, validate_register="25%", rng=5)
    again = kinecal.calibrate(model, sim.data, validate=moved, validate_register="25%", rng=5)
    other = kinecal.calibrate(model, sim.data, validate=moved, validate_register="25%", rng=6)
    assert part.val_after.size == 45 and part.val_after.mean() < 0.05
    np.testing.assert_array_equal(part.val_after, again.val_after)
    assert not np.array_equal(part.q_validation, other.q_validation)


def test_validation_in_the_calibration_frame_is_not_warned():
    model = kinecal.load_model("irb120")
    sim = kinecal.simulate(model, 80, noise=0.01, rng=3)
    val = kinecal.simulate(model, 40, errors=sim.true_params - model.nominal, noise=0.01,
                           rng=9)
    res = kinecal.calibrate(model, sim.data, validate=val.data)
    assert "validation-frame" not in [w.code for w in res.warnings]
    with pytest.raises(InputError, match="validation data only"):
        kinecal.calibrate(model, sim.data, validate_register="all")


def test_sigma_weighting_equals_the_explicit_weight_formula():
    """Rows weighted by c / (s^2 + tau^2) (position) and c / (L^2 (s_r^2 + tau_r^2))
    (rotation rows computed as L log(R R_m^T)), c giving a mean position weight of 1."""
    model = kinecal.load_model("irb120")
    free = ["a2", "a3", "d4", "alpha2", "theta3", "tool.x", "tool.y", "tool.z"]
    sim = kinecal.simulate(model, 50, rng=2, orientation=True, errors=dict(zip(
        free, [0.2, -0.1, 0.3, 1e-3, -2e-3, 0.5, 0.2, -0.4], strict=True)))
    gen = np.random.default_rng(8)
    s = np.c_[gen.uniform(0.005, 0.2, (50, 3)), gen.uniform(1e-5, 1e-3, (50, 3))]
    xyz = sim.data.xyz + gen.normal(size=(50, 3)) * s[:, :3]
    R = matrix_from_axis_angle(gen.normal(size=(50, 3)) * s[:, 3:]) @ sim.data.rotations
    tau = np.array([0.02, 2e-4])
    data = dataclasses.replace(sim.data, xyz=xyz, rotations=R, sigma=s, sigma_floor=tau)
    res = kinecal.calibrate(model, data, free=free)
    L = CalibrationProblem(model, data, free).rotation_weight
    var = s ** 2 + np.r_[tau[0], tau[0], tau[0], tau[1], tau[1], tau[1]] ** 2
    w = 1.0 / var
    c = 1.0 / w[:, :3].mean()
    w = c * w
    w[:, 3:] /= L ** 2
    np.testing.assert_allclose(sigma_row_scale(data, L), np.sqrt(w), rtol=1e-12)
    idx = model.index(free)

    def rows(x):
        p = model.nominal
        p[idx] = x
        T = model.fk(data.q, p)
        e = T[:, :3, 3] - xyz
        r = axis_angle_from_matrix(T[:, :3, :3] @ np.swapaxes(R, 1, 2)) * L
        return (np.c_[e, r] * np.sqrt(w)).ravel()

    ref = least_squares(rows, model.nominal[idx], method="lm", xtol=1e-15, ftol=1e-15)
    np.testing.assert_allclose(res.params[idx], ref.x, atol=1e-8)
    # a file's deviations without a floor: the floor is estimated from an unweighted fit
    est = kinecal.calibrate(model, dataclasses.replace(data, sigma_floor=None), free=free)
    floor = est.to_dict()["row_weights"]
    assert floor["floor_position"] < 0.05 and np.isfinite(floor["floor_rotation_rad"])


def test_per_axis_weights_beat_equal_weights_on_unequal_noise():
    """Noise 0.01 mm on x and y but 0.5 mm on z: weighting by the deviations identifies
    the arm closer to its truth than equal weights."""
    model = kinecal.load_model("irb120")
    sim = kinecal.simulate(model, 150, rng=4)
    s = np.tile([0.01, 0.01, 0.5], (150, 1))
    xyz = sim.data.xyz + np.random.default_rng(5).normal(size=(150, 3)) * s
    errs = []
    for sig in (None, s):
        data = dataclasses.replace(sim.data, xyz=xyz, sigma=sig)
        res = kinecal.calibrate(model, data)
        errs.append(np.linalg.norm(model.positions(sim.data.q, res.params)
                                   - model.positions(sim.data.q, sim.true_params), axis=1))
    assert errs[1].mean() < 0.5 * errs[0].mean()


def test_station_block_jacobian_matches_central_differences():
    model, _, data = _truth(n=12)
    block = StationBlock(data)
    p = model.nominal
    v0 = block.start(model, p) + np.r_[1.0, -2.0, 0.5, 0.01, -0.02, 0.03, 0, 0, 0, 0, 0, 0]
    cols = model.index(["a2", "alpha3", "tool.z"])
    rows = block.evaluate(model, p, v0, cols, jacobian=True)
    h = 1e-6
    for j in range(v0.size):
        d = np.zeros(v0.size)
        d[j] = h
        num = (block.evaluate(model, p, v0 + d).r - block.evaluate(model, p, v0 - d).r) / 2 / h
        np.testing.assert_allclose(rows.nuisance[:, j], num, rtol=1e-5, atol=1e-5)
    for j, k in enumerate(cols):
        d = np.zeros(model.n_params)
        d[k] = h
        num = (block.evaluate(model, p + d, v0).r - block.evaluate(model, p - d, v0).r) / 2 / h
        np.testing.assert_allclose(rows.arm[:, j], num, rtol=1e-5, atol=1e-5)
    assert xyz_rpy_from_transform(STATIONS[0]).shape == (6,)


def test_stations_have_their_own_identifiability_and_no_error_model(tmp_path, capsys):
    model, _, data = _truth(n=40, orientation=False)
    write_measurements(tmp_path / "rows.csv", data, model)
    assert main(["identifiability", "irb120", "--data", str(tmp_path / "rows.csv"),
                 "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert {"theta1", "d1"} <= set(report["unidentifiable"])  # the stations' blind motion
    with pytest.raises(InputError, match="one set-up"):
        from kinecal.calibration.serial.error_model import calibrate_error_model

        calibrate_error_model(model, data, "harmonic")
