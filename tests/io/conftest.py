"""Fixtures of tests/io: ur_description's own xacro (tests/data/ur_description) expanded by
the ``xacro`` package as ROS expands it, and the URDF it gives loaded with pinocchio."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import xacro

UR_DESCRIPTION = Path(__file__).resolve().parents[1] / "data" / "ur_description"
#: ur_description's arm joints, base to wrist (its tf_prefix left empty)
UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint")


class URDescription:
    """ur_description installed at `share` (its ``share/ur_description`` folder).

    xacro resolves ``$(find ur_description)`` with ament_index_python, which is not on
    PyPI; the installed copy has that substitution made already, with the path it evaluates
    to in a ROS install (the package's share folder). Meshes are ``package://`` names that
    nothing here loads (the ``$(find MESH_PACKAGE)`` left in ur_common.xacro is evaluated
    only with ``force_abs_paths:=true``; were it or any other ``$(find)`` reached, xacro
    would stop on the missing ament_index_python).
    """

    def __init__(self, share: Path):
        self.share = share

    def urdf(self, ur_type: str, kinematics: Path | None = None) -> str:
        """The URDF text of ``xacro ur.urdf.xacro ur_type:=TYPE [kinematics_params:=FILE]``."""
        mappings = {"ur_type": ur_type, "name": "ur"}
        if kinematics is not None:
            mappings["kinematics_params"] = str(kinematics)
        doc = xacro.process_file(str(self.share / "urdf" / "ur.urdf.xacro"), mappings=mappings)
        return doc.toxml()

    def tool0(self, ur_type: str, q: np.ndarray, kinematics: Path | None = None) -> np.ndarray:
        """``tool0`` in ``base`` (the controller's base frame), shape (N, 4, 4), metres, at
        joint angles `q` (N, 6) in radians, through pinocchio's URDF reader."""
        model = pin.buildModelFromXML(self.urdf(ur_type, kinematics))
        data = model.createData()
        base, tool0 = model.getFrameId("base"), model.getFrameId("tool0")
        joints = [model.joints[model.getJointId(name)] for name in UR_JOINTS]
        out = np.empty((len(q), 4, 4))
        for k, qk in enumerate(np.atleast_2d(q)):
            v = pin.neutral(model)
            for joint, angle in zip(joints, qk, strict=True):
                if joint.nq == 2:  # a continuous joint (the UR3's wrist 3): cos, sin
                    v[joint.idx_q:joint.idx_q + 2] = np.cos(angle), np.sin(angle)
                else:
                    v[joint.idx_q] = angle
            pin.framesForwardKinematics(model, data, v)
            out[k] = data.oMf[base].actInv(data.oMf[tool0]).homogeneous
        return out


@pytest.fixture(scope="session")
def ur_description(tmp_path_factory) -> URDescription:
    """The bundled ur_description files with ``$(find ur_description)`` resolved."""
    share = tmp_path_factory.mktemp("install") / "share" / "ur_description"
    shutil.copytree(UR_DESCRIPTION, share)
    for path in share.rglob("*.xacro"):
        path.write_text(path.read_text().replace("$(find ur_description)", str(share)))
    return URDescription(share)
