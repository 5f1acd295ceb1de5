"""Calibrations of the arms the first wave could not model: a prismatic axis, a positioner
behind two fixed frames, three markers on one flange."""

import dataclasses
import json

import numpy as np
import pinocchio as pin

from kinecal import calibrate, simulate
from kinecal.calibration.serial.simulate import random_configurations
from kinecal.cli import main
from kinecal.io.measurements import write_measurements
from kinecal.io.models import load_model, save_model
from kinecal.io.urdf_export import urdf_string
from kinecal.kinematics.serial.model import SerialModel

SIGMA = 0.01  # mm, per coordinate


def noise_floor(model, sim, res, val):
    """Mean validation error of the calibrated model over that of the true geometry on
    the same noisy validation data (1 = at the noise floor)."""
    truth = np.linalg.norm(model.positions(val.q, sim.true_params, val.marker) - val.xyz,
                           axis=1)
    return float(res.val_after.mean() / truth.mean())


def scara():
    """RRPR SCARA: joint 3 is the prismatic quill; the tracker sees it from 2 m away."""
    joints = [dict(theta=0.0, d=400.0, a=250.0, alpha=0.0),
              dict(theta=0.0, d=0.0, a=200.0, alpha=np.pi),
              dict(theta=0.0, d=0.0, a=0.0, alpha=0.0, type="prismatic"),
              dict(theta=0.0, d=50.0, a=0.0, alpha=0.0)]
    limits = [[-2.5, 2.5], [-2.5, 2.5], [0.0, 150.0], [-np.pi, np.pi]]
    return SerialModel("scara", "dh", joints, base=[2000.0, 300.0, -100.0, 0.01, -0.02, 1.2],
                       tool=[40.0, 10.0, 30.0], joint_limits=limits,
                       tolerances={"length": 0.5, "angle": 0.005})


def positioner():
    """Tilt-and-turn positioner seen by a camera: the camera is the measurement frame (base
    free), the positioner stands on a known floor plate and a known riser (two fixed frames),
    the target sits on a fixture whose pose is calibrated too (calibrate: true)."""
    joints = [
        {"frame": "floor_plate", "x": 1200.0, "y": -300.0, "z": 0.0, "rx": 0.0, "ry": 0.0,
         "rz": np.pi / 2},
        {"frame": "riser", "z": 650.0},
        dict(theta=0.0, d=0.0, a=0.0, alpha=-np.pi / 2),   # tilt
        dict(theta=0.0, d=180.0, a=0.0, alpha=0.0),        # turn table
        {"frame": "fixture", "x": 120.0, "y": 40.0, "z": 25.0, "calibrate": True},
    ]
    return SerialModel("positioner", "dh", joints, base=[0.0, 0.0, 2500.0, np.pi, 0.0, 0.0],
                       tool=[0.0, 0.0, 15.0], joint_limits=[[-1.5, 1.5], [-np.pi, np.pi]],
                       tolerances={"length": 0.5, "angle": 0.005})


def test_prismatic_arm_calibrates_to_the_noise_floor():
    model = scara()
    sim = simulate(model, 80, noise=SIGMA, rng=1)
    val = simulate(model, 200, errors=sim.true_params - model.nominal, noise=SIGMA, rng=2).data
    res = calibrate(model, sim.data, validate=val)
    assert res.val_before.mean() > 50 * SIGMA
    # the quill's direction in the tracker frame is found: d(tool)/d(q3) at every pose
    quill = model.joint_jacobian(val.q, res.params, "position")[:, :, 2]
    true_quill = model.joint_jacobian(val.q, sim.true_params, "position")[:, :, 2]
    np.testing.assert_allclose(np.linalg.norm(quill, axis=1), 1.0, atol=1e-12)
    assert np.abs(quill - true_quill).max() < 1e-4
    assert noise_floor(model, sim, res, val) < 1.1, res.summary()


def test_positioner_with_fixed_camera_mount_calibrates_to_the_noise_floor():
    model = positioner()
    assert {"floor_plate.x", "riser.z"} <= model.fixed_names
    assert "fixture.x" in model.calibratable
    sim = simulate(model, 60, noise=SIGMA, rng=3)
    val = simulate(model, 200, errors=sim.true_params - model.nominal, noise=SIGMA, rng=4).data
    np.testing.assert_array_equal(sim.true_params[model.index(["riser.z", "floor_plate.rz"])],
                                  [650.0, np.pi / 2])  # fixed frames stay as declared
    res = calibrate(model, sim.data, validate=val)
    assert not {"floor_plate.x", "riser.z"} & set(res.free)
    assert res.val_before.mean() > 50 * SIGMA
    assert noise_floor(model, sim, res, val) < 1.1, res.summary()


def test_three_markers_identify_all_three_tool_points(tmp_path, capsys):
    points = {"A": [0.0, 0.0, 31.0], "B": [52.0, -3.0, 20.0], "C": [-4.0, 61.0, 25.0]}
    # the flange frame is the robot's design (its last link held): the markers' points in
    # it are then identifiable, all nine coordinates
    arm = dataclasses.replace(load_model("irb120"), fixed=("theta6", "d6", "a6", "alpha6"))
    model = arm.with_markers(points)
    sim = simulate(model, 30, rng=5)  # 30 configurations x 3 markers, noise-free
    marker_names = [f"tool.{m}.{c}" for m in "ABC" for c in "xyz"]
    true = sim.true_params[model.index(marker_names)]
    assert np.abs(true - model.nominal[model.index(marker_names)]).max() > 0.1
    res = calibrate(model, sim.data)
    assert set(marker_names) <= set(res.free)
    np.testing.assert_allclose(res.params[model.index(marker_names)], true, rtol=0, atol=1e-9)
    assert res.errors_after.max() < 1e-9
    # the same from a CSV with a marker column, for a model file without markers: the
    # command line gives it one tool point per marker the file names
    data = tmp_path / "three.csv"
    write_measurements(data, sim.data, model)
    save_model(arm, tmp_path / "arm.yaml")
    out = tmp_path / "r.json"
    assert main(["calibrate", str(tmp_path / "arm.yaml"), str(data), "--out", str(out),
                 "--quiet"]) == 0
    table = json.loads(out.read_text())["parameters"]
    np.testing.assert_allclose([table[n]["identified"] for n in marker_names], true, atol=1e-9)
    # and the exported URDF carries one tool link per marker
    urdf = tmp_path / "three.urdf"
    assert main(["export", str(out), "--nominal", str(tmp_path / "arm.yaml"), "--out",
                 str(urdf)]) == 0
    capsys.readouterr()
    pm = pin.buildModelFromUrdf(str(urdf))
    pd = pm.createData()
    q = random_configurations(arm, 20, np.random.default_rng(6))
    for m, name in enumerate("ABC"):
        fid = pm.getFrameId(f"tool_{name}")
        theirs = []
        for qi in q:
            pin.framesForwardKinematics(pm, pd, qi)
            theirs.append(pd.oMf[fid].translation * 1000.0)
        mine = res.model.positions(q, marker=np.full(len(q), m))
        np.testing.assert_allclose(np.array(theirs), mine, rtol=0, atol=1e-9)
    assert "tool_A_joint" in urdf_string(res.model)
