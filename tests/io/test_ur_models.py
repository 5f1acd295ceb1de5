"""The bundled UR models (``ur3`` ... ``ur30``): `kinecal models` lists them; their flange
is ur_description's ``tool0`` in the controller's ``base`` frame, checked against two
sources kinecal does not share code with: ur_description's own xacro with its kinematics
file of every type (tests/data/ur_description, expanded by the xacro package) and, for the
UR3, UR5 and UR10, the ROS-Industrial URDFs of example-robot-data through pinocchio."""

from __future__ import annotations

import importlib.metadata
import json

import numpy as np
import pinocchio as pin
import pytest

from kinecal.cli import main
from kinecal.io.models import load_model
from kinecal.io.ur.robots import UR_TYPES, ur_model

Q = np.random.default_rng(21).uniform(-2 * np.pi, 2 * np.pi, (200, 6))


def _flange(name: str) -> np.ndarray:
    """The bundled model's flange (m), without its tool point (the ur5's carries one)."""
    model = load_model(name)
    p = model.nominal
    p[model.index(["tool.x", "tool.y", "tool.z"])] = 0.0
    T = model.fk(Q, p)
    T[:, :3, 3] /= 1000.0
    return T


def test_every_ur_type_is_a_bundled_model(capsys):
    assert main(["models", "--json"]) == 0
    listed = {m["name"] for m in json.loads(capsys.readouterr().out)["models"]}
    assert set(UR_TYPES) <= listed
    for name in UR_TYPES:  # the files are the table of kinecal.io.ur
        model, table = load_model(name), ur_model(name)
        np.testing.assert_allclose(model.nominal[:24], table.nominal[:24], rtol=0,
                                   atol=1e-12)


@pytest.mark.parametrize("name", list(UR_TYPES))
def test_flange_is_ur_descriptions_tool0(ur_description, name):
    """``xacro ur.urdf.xacro ur_type:=NAME`` with its default_kinematics.yaml (its pi/2
    written 1.570796327): tool0 in base is the bundled model's flange to 1e-6 mm."""
    theirs = ur_description.tool0(name, Q)
    ours = _flange(name)
    assert np.abs(theirs[:, :3, 3] - ours[:, :3, 3]).max() < 1e-9  # m
    assert np.abs(theirs[:, :3, :3] - ours[:, :3, :3]).max() < 1e-9


def _example_robot_data(rel: str) -> str:
    dist = importlib.metadata.distribution("example-robot-data")
    return str(dist.locate_file(f"cmeel.prefix/share/example-robot-data/robots/{rel}"))


@pytest.mark.parametrize("name", ["ur3", "ur5", "ur10"])
def test_flange_is_the_ros_industrial_urdfs_tool0_in_base(name):
    """example-robot-data's ur_description URDF through pinocchio: ``tool0`` in ``base``
    (the controller's frames) is the bundled model's flange."""
    model = pin.buildModelFromUrdf(_example_robot_data(f"ur_description/urdf/{name}_robot.urdf"))
    data = model.createData()
    base, tool0 = model.getFrameId("base"), model.getFrameId("tool0")
    joints = [model.getJointId(j) for j in ("shoulder_pan_joint", "shoulder_lift_joint",
                                            "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                                            "wrist_3_joint")]
    ours = _flange(name)
    worst_p = worst_R = 0.0
    for qi, T in zip(Q, ours, strict=True):
        q = pin.neutral(model)
        for j, v in zip(joints, qi, strict=True):
            q[model.joints[j].idx_q] = v
        pin.framesForwardKinematics(model, data, q)
        rel = data.oMf[base].actInv(data.oMf[tool0])
        worst_p = max(worst_p, float(np.abs(rel.translation - T[:3, 3]).max()))
        worst_R = max(worst_R, float(np.abs(rel.rotation - T[:3, :3]).max()))
    assert worst_p < 1e-9 and worst_R < 1e-9  # m
