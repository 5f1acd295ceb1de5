"""Self-collision in the Plan view, from the collision meshes of a real URDF
(example-robot-data's UR5): the arm at zero and in its usual poses is free; with the elbow
folded (3.1 rad) the wrist goes through the upper arm, and the Plan view refuses the pose
with the pairs named."""

from __future__ import annotations

import importlib.metadata

import numpy as np
import pytest

from kinecal.errors import InputError


def ur5_urdf() -> str:
    dist = importlib.metadata.distribution("example-robot-data")
    return str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots/"
                                "ur_description/urdf/ur5_robot.urdf"))


def test_a_folded_elbow_collides_and_the_plan_refuses_it(tmp_path, monkeypatch):
    from kinecal.ui.app import Workbench

    monkeypatch.chdir(tmp_path)
    wb = Workbench(ur5_urdf(), port=0, workdir="kinecal-ui", tip_links=["tool0"])
    try:
        plan = wb.plan
        assert plan.collider is not None
        free = [[0, 0, 0, 0, 0, 0], [0, -90, 0, -90, 0, 0], [30, -60, 90, -120, -90, 45]]
        for q in free:
            for sl, v in zip(plan.sliders, q, strict=True):
                sl.value = float(v)
            assert plan._collisions(plan.q_now()) == []
            plan.add_pose()
        assert len(wb.session.plan) == 3
        for sl, v in zip(plan.sliders, [0, 0, 177.6, 0, 0, 0], strict=True):  # 3.1 rad
            sl.value = float(v)
        hits = plan._collisions(plan.q_now())
        assert ("upper_arm_link", "wrist_1_link") in hits
        with pytest.raises(InputError, match=r"collides with itself: .*upper_arm_link with "
                                             r"wrist_1_link"):
            plan.add_pose()
        assert len(wb.session.plan) == 3
        assert "collides: " in wb.plan.figures.content
        assert np.allclose(wb.session.plan[2], np.radians(free[2]))
    finally:
        wb.close()
