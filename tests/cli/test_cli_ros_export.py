"""``kinecal export`` of a hand-eye result for ROS: ``--format ros-tf`` (frames, the
static_transform_publisher arguments, a ROS 2 launch file) and ``--format urdf --camera``
(the camera mount as a fixed joint, checked with pinocchio)."""

from __future__ import annotations

import json
import shlex
import sys
import types

import numpy as np
import pinocchio as pin
import pytest

from kinecal.cli import main
from kinecal.io.models import load_model
from kinecal.spatial import matrix_from_quaternion, transform_from_pq


def _result(tmp_path, setup="eye-in-hand", unit="mm", seed=0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=4)
    X = transform_from_pq(np.r_[rng.uniform(-80, 80, 3), q / np.linalg.norm(q)])
    path = tmp_path / f"he-{setup}.json"
    data = {"X": X.tolist(), "setup": setup, "method": "park"}
    if unit is not None:
        data["length_unit"] = unit
    path.write_text(json.dumps(data))
    return path, X


def _launch_arguments(path):
    """The arguments of the Node in a launch file, run with stand-in launch modules."""
    found = {}

    def node(**kw):
        found.update(kw)
        return kw

    stubs = {"launch": types.SimpleNamespace(LaunchDescription=list),
             "launch_ros": types.ModuleType("launch_ros"),
             "launch_ros.actions": types.SimpleNamespace(Node=node)}
    saved = {k: sys.modules.get(k) for k in stubs}
    sys.modules.update(stubs)
    try:
        scope: dict = {}
        exec(compile(path.read_text(), str(path), "exec"), scope)
        scope["generate_launch_description"]()
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v
    return found


def _pose_of(args):
    val = {args[i]: args[i + 1] for i in range(0, len(args), 2)}
    xyz = [float(val[k]) for k in ("--x", "--y", "--z")]
    R = matrix_from_quaternion([float(val[k]) for k in ("--qw", "--qx", "--qy", "--qz")])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, xyz
    return T, val["--frame-id"], val["--child-frame-id"]


@pytest.mark.parametrize(("setup", "parent"), [("eye-in-hand", "tool0"),
                                               ("eye-to-hand", "base_link")])
def test_ros_tf_launch_file_and_command_publish_X(tmp_path, capsys, setup, parent):
    res, X = _result(tmp_path, setup)
    out = tmp_path / "handeye.launch.py"
    assert main(["export", str(res), "--format", "ros-tf", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    node = _launch_arguments(out)
    assert node["package"] == "tf2_ros" and node["executable"] == "static_transform_publisher"
    T, frame, child = _pose_of(node["arguments"])
    assert (frame, child) == (parent, "camera_optical_frame")
    np.testing.assert_allclose(T[:3, :3], X[:3, :3], atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], X[:3, 3] / 1000.0, atol=1e-15)
    words, command = stdout.splitlines()[:2]
    assert f"parent frame (frame_id) {parent}, child frame (child_frame_id) " \
           "camera_optical_frame" in words
    assert f"pose of camera_optical_frame in {parent}" in words
    assert f"maps camera_optical_frame coordinates to {parent} coordinates" in words
    tokens = shlex.split(command)
    assert tokens[:4] == ["ros2", "run", "tf2_ros", "static_transform_publisher"]
    assert tokens[4:] == node["arguments"]


def test_ros_tf_frames_units_and_refusals(tmp_path, capsys):
    res, X = _result(tmp_path, unit="m")
    out = tmp_path / "t.launch.py"
    assert main(["export", str(res), "--out", str(out), "--parent-frame", "flange",
                 "--child-frame", "cam_color_optical_frame"]) == 0  # format from the suffix
    T, frame, child = _pose_of(_launch_arguments(out)["arguments"])
    assert (frame, child) == ("flange", "cam_color_optical_frame")
    np.testing.assert_allclose(T[:3, 3], X[:3, 3], atol=1e-13)
    capsys.readouterr()
    res2, _ = _result(tmp_path, setup="eye-to-hand", unit=None)
    out2 = tmp_path / "u.launch.py"
    assert main(["export", str(res2), "--format", "ros-tf", "--out", str(out2)]) == 2
    assert "give --unit mm or --unit m" in capsys.readouterr().err and not out2.exists()
    assert main(["export", "ur5", "--format", "ros-tf", "--out", str(out2)]) == 2
    assert not out2.exists()
    assert main(["export", str(res), "--format", "urdf", "--out", str(tmp_path / "a.urdf")]) \
        == 2
    assert "--camera" in capsys.readouterr().err


@pytest.mark.parametrize("setup", ["eye-in-hand", "eye-to-hand"])
def test_urdf_with_camera_mount(tmp_path, capsys, setup):
    res, X = _result(tmp_path, setup, seed=3)
    out = tmp_path / "ur5_camera.urdf"
    assert main(["export", "ur5", "--format", "urdf", "--camera", str(res), "--out",
                 str(out)]) == 0
    assert "camera mount" in capsys.readouterr().err
    robot = pin.buildModelFromUrdf(str(out))
    data = robot.createData()
    cam = robot.getFrameId("camera_optical_frame")
    model = load_model("ur5")
    p = model.nominal
    p[model.index(["tool.x", "tool.y", "tool.z"])] = 0.0
    q = np.random.default_rng(1).uniform(-3, 3, (20, 6))
    flange = model.fk(q, p)
    for qi, F in zip(q, flange, strict=True):
        pin.framesForwardKinematics(robot, data, qi)
        M = data.oMf[cam]
        want = F @ X if setup == "eye-in-hand" else X  # base == measurement frame here
        np.testing.assert_allclose(M.translation * 1000.0, want[:3, 3], atol=1e-9)
        np.testing.assert_allclose(M.rotation, want[:3, :3], atol=1e-12)
