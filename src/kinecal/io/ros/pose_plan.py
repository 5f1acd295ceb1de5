"""`import_pose_plan`: a bag of capture poses, one message per pose, as joint rows.

robot_calibration records the poses a calibration visits as ``calibration_poses.bag``: one
``robot_calibration_msgs/CaptureConfig`` per pose (the JointState to move to and the
feature detectors to run), or, in its older recordings, one ``sensor_msgs/JointState`` per
pose. Each message is one row: no dwell is searched, the rows are the poses in the bag's
order (a pose plan, as ``kinecal fk`` and ``kinecal simulate`` read one). Joints are mapped
as for a recording (`kinecal.io.ros.joints`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinecal.errors import InputError
from kinecal.io.ros import messages as msgs
from kinecal.io.ros.bag import Bag
from kinecal.io.ros.importer import BagImport, ImportOptions
from kinecal.io.ros.joints import JointMapper
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["import_pose_plan"]

_PER_M = {"m": 1.0, "mm": 1000.0}


def import_pose_plan(path: str | Path, model: SerialModel, opts: ImportOptions) -> BagImport:
    """The joints of every message on ``opts.joints``, one row each (module docstring).

    Returns
    -------
    BagImport
        ``q`` ``(K, n_joints)`` (rad; prismatic: the model's length unit) and ``kept`` the
        message indices; no dwells. Messages without the model's joints, with fewer
        positions than names or with non-finite positions are left out (``dropped``, with
        the reason).

    Raises
    ------
    InputError
        A missing topic or one of another type, joint names that do not map (see
        `kinecal.io.ros.joints`), no usable message.
    """
    mapper = JointMapper(model.n_joints, opts.joint_names, opts.joints)
    scale = np.where(model.is_prismatic(), _PER_M[model.length_unit], 1.0)
    out = BagImport([], [], joints_how="")
    rows = []
    with Bag(path) as bag:
        bag.check_topic(opts.joints, "--joints")
        for k, (_topic, kind, _ns, raw) in enumerate(bag.stream([opts.joints])):
            names, pos = msgs.joint_state(bag.decode(raw, kind))
            why = None
            if len(pos) != len(names):
                why = f"{len(names)} names but {len(pos)} positions"
            else:
                idx = mapper.index(names)
                if idx is None:
                    why = "without the model's joints"
                elif not np.isfinite(pos[idx]).all():
                    why = "positions not finite"
            if why is not None:
                out.dropped.append((k, why))
                continue
            out.kept.append(k)
            rows.append(pos[idx] * scale)
    out.samples = len(out.kept) + len(out.dropped)
    if not out.samples:
        raise InputError(f"topic {opts.joints} has no message", option="--joints")
    if not rows:
        if any(w == "without the model's joints" for _, w in out.dropped):
            raise mapper.fail()
        first = f" (message 1: {out.dropped[0][1]})" if out.dropped else ""
        raise InputError(f"topic {opts.joints}: no message gives the model's "
                         f"{model.n_joints} joints{first}", file=path)
    out.q = np.array(rows)
    out.joints_how = mapper.how or ""
    return out
