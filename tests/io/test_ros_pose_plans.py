"""Bags of capture poses (robot_calibration's ``calibration_poses.bag``: one
``robot_calibration_msgs/CaptureConfig``, or in older recordings one JointState, per pose)
become a joints CSV, a pose plan; joint names that do not say the order are refused
unless --joint-names does; a URDF model's chain is chosen with --base-link/--tip-link (a
Panda from example-robot-data). Bags are written here with rosbags' writers."""

from __future__ import annotations

import importlib.metadata
import importlib.util
from pathlib import Path

import numpy as np
import pytest
from rosbags.typesys import get_types_from_msg

from kinecal.cli import main
from kinecal.io.csvtable import read_table


def _sibling(name):
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


BagWriter = _sibling("test_ros_bags").BagWriter
#: robot_calibration_msgs/msg/CaptureConfig.msg (mikeferguson/robot_calibration), for the
#: writer's type store
CAPTURE = "sensor_msgs/JointState joint_states\nstring[] features\n"
UR = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
      "wrist_2_joint", "wrist_3_joint"]
POSES = np.random.default_rng(5).uniform(-2.5, 2.5, (7, 6))  # rad


def write_poses(path, kind, names, poses, capture=True, topic="calibration_joint_states"):
    """One message per pose, as robot_calibration's capture_poses writes them."""
    w = BagWriter(path, kind)
    name = "robot_calibration_msgs/msg/CaptureConfig"
    w.ts.register(get_types_from_msg(CAPTURE, name))
    e = np.zeros(0)
    for k, q in enumerate(poses):
        js = w.T("sensor_msgs/msg/JointState")(header=w.header(1.0 + k), name=list(names),
                                               position=np.ascontiguousarray(q, float), velocity=e,
                                               effort=e)
        msg = w.T(name)(joint_states=js, features=["checkerboard_finder"]) if capture else js
        w.write(topic, 1.0 + 3.0 * k, msg)
    w.close()
    return path


def joints_csv(path, n):
    table = read_table(path, [f"q{i}" for i in range(1, n + 1)])
    return np.column_stack([table[f"q{i}"] for i in range(1, n + 1)])


@pytest.mark.parametrize("kind", ["sqlite3", "ros1"])
def test_capture_config_bag_is_a_pose_plan(tmp_path, capsys, kind):
    """Names as capture_poses accumulates them (a head joint too, the arm's in another
    order): one row per message, the arm's joints in degrees."""
    names = ["head_pan_joint", *UR[::-1]]
    poses = np.c_[np.full(len(POSES), 0.3), POSES[:, ::-1]]
    bag = write_poses(tmp_path / ("poses.bag" if kind == "ros1" else "poses"), kind, names,
                      poses)
    out = tmp_path / "plan.csv"
    assert main(["import", str(bag), "--model", "ur5", "--joints", "calibration_joint_states",
                 "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "7 poses from 7 messages" in err and "mapped by UR joint names" in err
    np.testing.assert_allclose(joints_csv(out, 6), np.degrees(POSES), rtol=0, atol=1e-9)
    assert main(["fk", "ur5", str(out)]) == 0  # a plan kinecal reads


def test_older_joint_state_pose_bag_with_per_message(tmp_path, capsys):
    bag = write_poses(tmp_path / "old.mcap", "mcap", UR, POSES, capture=False)
    out = tmp_path / "plan.csv"
    assert main(["import", str(bag), "--model", "ur5", "--joints", "calibration_joint_states",
                 "--per-message", "--out", str(out)]) == 0
    np.testing.assert_allclose(joints_csv(out, 6), np.degrees(POSES), rtol=0, atol=1e-9)
    # without the flag a JointState topic is a recording: seven lone samples, no dwell
    out2 = tmp_path / "none.csv"
    assert main(["import", str(bag), "--model", "ur5", "--joints", "calibration_joint_states",
                 "--out", str(out2)]) == 2
    assert "no dwell" in capsys.readouterr().err and not out2.exists()
    # a pose plan has no measurements
    assert main(["import", str(bag), "--model", "ur5", "--joints", "calibration_joint_states",
                 "--per-message", "--points", "/tracker", "--out", str(out2)]) == 2
    assert "--points" in capsys.readouterr().err


def test_names_that_do_not_say_the_order_are_refused(tmp_path, capsys):
    """Was: mapped by message order with a 'mapped by order' line (joints scrambled)."""
    shuffled = ["elbow", "base", "wrist_c", "shoulder", "wrist_a", "wrist_b"]
    order = [1, 3, 0, 4, 5, 2]  # the model's joint i is the bag's shuffled[order[i]]
    poses = np.empty_like(POSES)
    poses[:, order] = POSES
    bag = write_poses(tmp_path / "p", "sqlite3", shuffled, poses)
    out = tmp_path / "plan.csv"
    args = ["import", str(bag), "--model", "ur5", "--joints", "calibration_joint_states",
            "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "--joint-names" in err and "do not say which" in err and not out.exists()
    names = ",".join(shuffled[k] for k in order)
    assert main([*args, "--joint-names", names]) == 0
    np.testing.assert_allclose(joints_csv(out, 6), np.degrees(POSES), rtol=0, atol=1e-9)
    # names that number the joints say the order themselves, shuffled or not
    numbered = [f"joint_{m + 1}" for m in np.argsort(order)]  # slot order[m] holds joint m
    bag2 = write_poses(tmp_path / "n", "sqlite3", numbered, poses)
    out2 = tmp_path / "plan2.csv"
    assert main(["import", str(bag2), "--model", "ur5", "--joints",
                 "calibration_joint_states", "--out", str(out2)]) == 0
    assert "mapped by joint number" in capsys.readouterr().err
    np.testing.assert_allclose(joints_csv(out2, 6), np.degrees(POSES), rtol=0, atol=1e-9)


def test_a_panda_urdf_imports_with_its_tip_link(tmp_path, capsys):
    """--base-link/--tip-link reach the model (the Panda has two finger branches)."""
    dist = importlib.metadata.distribution("example-robot-data")
    panda = dist.locate_file("cmeel.prefix/share/example-robot-data/robots/panda_description/"
                             "urdf/panda.urdf")
    names = [f"panda_joint{k}" for k in range(1, 8)] + ["panda_finger_joint1",
                                                         "panda_finger_joint2"]
    poses = np.c_[np.random.default_rng(8).uniform(-1.5, 1.5, (5, 7)), np.full((5, 2), 0.02)]
    bag = write_poses(tmp_path / "panda", "sqlite3", names[::-1], poses[:, ::-1])
    out = tmp_path / "plan.csv"
    args = ["import", str(bag), "--model", str(panda), "--joints", "calibration_joint_states",
            "--out", str(out)]
    assert main(args) == 2 and "--tip-link" in capsys.readouterr().err
    assert main([*args, "--base-link", "panda_link0", "--tip-link", "panda_link8"]) == 0
    assert "mapped by name" in capsys.readouterr().err
    np.testing.assert_allclose(joints_csv(out, 7), np.degrees(poses[:, :7]), rtol=0,
                               atol=1e-9)
