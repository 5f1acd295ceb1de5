"""Robot systems (kinecal.kinematics.tree): FK of every chain of real tree URDFs against
pinocchio (mimic joints included), the analytic system Jacobian against central
differences, link poses, one tip as a serial model, bad trees refused.

The URDFs are example-robot-data's (TALOS: torso, two arms and the head; Baxter: two arms
and a mimic finger; TIAGo dual) and rtb-data's; pinocchio builds them with ``mimic=True``.
"""

import importlib.metadata

import numpy as np
import pinocchio as pin
import pytest

from kinecal.errors import InputError
from kinecal.io.urdf_tree import load_urdf_system
from kinecal.kinematics.tree import SystemModel
from kinecal.spatial import axis_angle_from_matrix


def robot_file(rel: str) -> str:
    dist = importlib.metadata.distribution("example-robot-data")
    return str(dist.locate_file(f"cmeel.prefix/share/example-robot-data/robots/{rel}"))


TREES = {
    "talos": ("talos_data/robots/talos_reduced.urdf",
              ["gripper_left_base_link", "gripper_right_base_link", "head_2_link"]),
    "baxter": ("baxter_description/urdf/baxter.urdf",
               ["left_gripper", "right_gripper", "l_gripper_r_finger"]),
    "tiago-dual": ("tiago_description/robots/tiago_dual.urdf",
                   ["arm_left_tool_link", "arm_right_tool_link"]),
}


def pinocchio_config(model, system, q):
    """A pinocchio configuration of the system's joint readings `q` (n_joints,)."""
    qp = pin.neutral(model)
    for k, name in enumerate(system.joint_names):
        jm = model.joints[model.getJointId(name)]
        if jm.nq == 1:
            qp[jm.idx_q] = q[k]
        else:  # continuous: (cos, sin)
            qp[jm.idx_q:jm.idx_q + 2] = [np.cos(q[k]), np.sin(q[k])]
    return qp


def random_q(system, n, seed):
    lo, hi = system.joint_limits[:, 0], np.minimum(system.joint_limits[:, 1], 3.0)
    lo = np.maximum(lo, -3.0)
    return np.random.default_rng(seed).uniform(lo, hi, (n, system.n_joints))


@pytest.mark.parametrize("name", sorted(TREES))
def test_every_tip_matches_pinocchio(name):
    rel, tips = TREES[name]
    path = robot_file(rel)
    system = load_urdf_system(path, tips)
    model = pin.buildModelFromUrdf(path, mimic=True)
    data = model.createData()
    q = random_q(system, 12, 0)
    worst = 0.0
    for i in range(len(q)):
        pin.framesForwardKinematics(model, data, pinocchio_config(model, system, q[i]))
        for t, tip in enumerate(system.tips):
            T = data.oMf[model.getFrameId(tip)].homogeneous
            mine = system.fk(q[i:i + 1], marker=np.array([t]))[0]
            worst = max(worst, float(np.abs(T - mine).max()))
            link = system.link_poses(q[i:i + 1], tip)[0]  # the link itself (tool at zero)
            worst = max(worst, float(np.abs(T - link).max()))
    assert worst < 1e-14  # metres and rotation entries


def test_baxter_mimic_finger_is_a_joint_with_a_multiplier():
    system = load_urdf_system(robot_file(TREES["baxter"][0]), TREES["baxter"][1])
    assert "l_gripper_l_finger_joint" in system.joint_names  # the leader reads
    assert "l_gripper_r_finger_joint" not in system.joint_names  # the follower does not
    k = system.index(["l_gripper_r_finger_joint.multiplier"])[0]
    assert system.nominal[k] == -1.0
    assert "l_gripper_r_finger_joint.multiplier" in system.calibratable


def _numeric(system, q, p, tips, h=1e-7):
    J = np.zeros((system.n_params, 6, len(q)))
    for k in range(system.n_params):
        d = np.zeros(system.n_params)
        d[k] = h
        Tp, Tm = system.fk(q, p + d, tips), system.fk(q, p - d, tips)
        J[k, :3] = ((Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)).T
        J[k, 3:] = (axis_angle_from_matrix(Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2))
                    / (2 * h)).T
    return J


def test_system_jacobian_matches_central_differences():
    system = load_urdf_system(robot_file(TREES["baxter"][0]), TREES["baxter"][1])
    rng = np.random.default_rng(1)
    q = random_q(system, 9, 1)
    tips = rng.integers(0, 3, 9)
    p = system.nominal + rng.normal(0.0, 1e-3, system.n_params)
    J = system.jacobian_t(q, p, "pose", marker=tips)
    np.testing.assert_allclose(J, _numeric(system, q, p, tips), rtol=0, atol=2e-8)
    # the sweep and the chunked Jacobian agree bit for bit on a column subset; the sweep's
    # frames and the point kernel's positions to round-off
    cols = system.index(["l_gripper_r_finger_joint.multiplier", "left_s0.offset", "base.x"])
    sweep = system.sweep(q, p, tips)
    np.testing.assert_array_equal(sweep.jacobian_t("pose", cols), J[cols])
    np.testing.assert_allclose(sweep.positions, system.positions(q, p, tips), atol=1e-15)
    # the joint Jacobian (a mimic joint's column adds to its leader's, times -1)
    Jq = system.joint_jacobian(q, p, "pose", tips)
    h = 1e-7
    for j in range(system.n_joints):
        d = np.zeros(system.n_joints)
        d[j] = h
        Tp, Tm = system.fk(q + d, p, tips), system.fk(q - d, p, tips)
        num = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)
        np.testing.assert_allclose(Jq[:, :3, j], num, rtol=0, atol=2e-8)


def test_link_points_and_their_jacobian():
    system = load_urdf_system(robot_file(TREES["talos"][0]), TREES["talos"][1])
    rng = np.random.default_rng(2)
    q = random_q(system, 7, 2)
    p = system.nominal + rng.normal(0.0, 1e-3, system.n_params)
    link = "arm_left_4_link"
    pts = rng.normal(0.0, 0.1, (7, 3))
    cols = np.arange(system.n_params)
    P, J, R = system.link_points(q, link, pts, p, cols)
    T = system.link_poses(q, link, p)
    np.testing.assert_allclose(P, np.einsum("nij,nj->ni", T[:, :3, :3], pts) + T[:, :3, 3],
                               atol=1e-15)
    np.testing.assert_allclose(R, T[:, :3, :3], atol=0)
    h = 1e-7
    num = np.zeros_like(J)
    for k in cols:
        d = np.zeros(system.n_params)
        d[k] = h
        num[k] = ((system.link_points(q, link, pts, p + d)[0]
                   - system.link_points(q, link, pts, p - d)[0]) / (2 * h)).T
    np.testing.assert_allclose(J, num, rtol=0, atol=2e-8)
    # the link sweep: origin and frame, with its pose Jacobian
    s = system.link_sweep(q, link, p)
    np.testing.assert_allclose(s.positions, T[:, :3, 3], atol=1e-15)
    assert s.jacobian_t("pose").shape == (system.n_params, 6, 7)


def test_tip_model_is_the_chain_as_a_serial_model():
    system = load_urdf_system(robot_file(TREES["talos"][0]), TREES["talos"][1])
    p = system.nominal + np.random.default_rng(3).normal(0.0, 1e-3, system.n_params)
    q = random_q(system, 20, 3)
    for t, tip in enumerate(system.tips):
        serial = system.tip_model(tip, p)
        src = system.chain_joints(tip)
        assert tuple(e["name"] for e in serial.joints) == tuple(
            system.joint_names[s] for s in src)
        np.testing.assert_allclose(serial.fk(q[:, src]), system.fk(q, p, np.full(20, t)),
                                   rtol=0, atol=4e-15)
    shared = set(system.shared_parameters())
    assert {"torso_1_joint.offset", "torso_2_joint.offset", "base.x"} <= shared
    assert "arm_left_1_joint.offset" not in shared


def test_coupled_chain_has_no_serial_model():
    system = load_urdf_system(robot_file(TREES["baxter"][0]), TREES["baxter"][1])
    with pytest.raises(InputError, match="coupled"):
        system.tip_model("l_gripper_r_finger")


MIMIC = """<robot name="m">
  <link name="b"/><link name="l1"/><link name="l2"/><link name="l3"/>
  <joint name="j1" type="revolute"><parent link="b"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>{m1}</joint>
  <joint name="j2" type="revolute"><origin xyz="0.3 0 0"/><parent link="l1"/>
    <child link="l2"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1"
    velocity="1"/>{m2}</joint>
  <joint name="j3" type="revolute"><origin xyz="0.2 0 0"/><parent link="l2"/>
    <child link="l3"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1"
    velocity="1"/>{m3}</joint>
</robot>"""


def _mimic_file(tmp_path, m1="", m2="", m3=""):
    path = tmp_path / f"m{len(list(tmp_path.iterdir()))}.urdf"
    path.write_text(MIMIC.format(m1=m1, m2=m2, m3=m3))
    return path


def test_mimic_of_a_mimic_resolves_to_the_leader(tmp_path):
    path = _mimic_file(tmp_path, m2='<mimic joint="j1" multiplier="2" offset="0.1"/>',
                       m3='<mimic joint="j2" multiplier="-0.5" offset="0.2"/>')
    system = load_urdf_system(path, ["l3"])
    assert system.joint_names == ("j1",)
    # pinocchio takes no mimic of a mimic: the same law written out, j3 = -0.5 (2 j1 + 0.1)
    # + 0.2 = -j1 + 0.15
    flat = _mimic_file(tmp_path, m2='<mimic joint="j1" multiplier="2" offset="0.1"/>',
                       m3='<mimic joint="j1" multiplier="-1" offset="0.15"/>')
    model = pin.buildModelFromUrdf(str(flat), mimic=True)
    data = model.createData()
    for q in (0.3, -1.1):
        qp = pin.neutral(model)
        qp[model.joints[model.getJointId("j1")].idx_q] = q
        pin.framesForwardKinematics(model, data, qp)
        np.testing.assert_allclose(system.fk(np.array([[q]]))[0],
                                   data.oMf[model.getFrameId("l3")].homogeneous, atol=1e-15)
    assert system.nominal[system.index(["j3.multiplier"])[0]] == -1.0  # -0.5 * 2


@pytest.mark.parametrize(("m1", "m2", "m3", "tips", "match"), [
    ('<mimic joint="j2"/>', '<mimic joint="j1"/>', "", ["l3"], "cycle"),
    ("", '<mimic joint="nope"/>', "", ["l3"], "not a joint"),
    ("", "", "", ["l3", "nope"], "no link 'nope'"),
    ("", "", "", ["l3", "l3"], "given twice"),
])
def test_bad_trees_are_refused(tmp_path, m1, m2, m3, tips, match):
    path = _mimic_file(tmp_path, m1, m2, m3)
    with pytest.raises(InputError, match=match):
        load_urdf_system(path, tips)


def test_rows_name_known_tips_and_readings_fit():
    system = load_urdf_system(robot_file(TREES["tiago-dual"][0]), TREES["tiago-dual"][1])
    q = random_q(system, 3, 4)
    with pytest.raises(InputError, match="tip"):
        system.positions(q, marker=np.array([0, 1, 2]))
    with pytest.raises(InputError, match="joint values"):
        system.positions(q[:, :3])
    with pytest.raises(InputError, match="unknown tip"):
        system.tip_number("arm_left_7_link")
    assert isinstance(system, SystemModel) and system.marker_names == system.tips
