"""Batch inverse kinematics: round trips on every bundled arm and convention, unreachable
and joint-limited targets, singular configurations, restarts, determinism, bad input."""

import numpy as np
import pytest

from kinecal.calibration.serial.simulate import random_configurations
from kinecal.errors import InputError
from kinecal.io.models import load_model
from kinecal.kinematics.serial.ik import (
    STATUS,
    characteristic_length,
    default_tol_position,
    solve_ik,
)
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import matrix_from_axis_angle, pose_errors

ARMS = ["ur5", "irb120", "puma560", "kr6-craig", "hu2005-scanner"]


def neighbourhood(model, n, rng, sigma=0.1):
    """Random configurations within the limits and seeds perturbed by N(0, sigma rad)."""
    q = random_configurations(model, n, rng)
    return q, q + rng.normal(0.0, sigma, q.shape)


def check_reported_errors(model, res, targets, params=None):
    """The errors an IKResult reports are those of an independent FK evaluation."""
    T = model.fk(res.q, params)
    if targets.ndim == 3:
        rot, pos = pose_errors(T, targets)
        np.testing.assert_allclose(res.rotation_error, rot, rtol=1e-6, atol=1e-15)
    else:
        pos = np.linalg.norm(T[:, :3, 3] - targets, axis=1)
    np.testing.assert_allclose(res.position_error, pos, rtol=1e-6, atol=1e-15)
    lim = model.joint_limits
    assert ((res.q >= lim[:, 0]) & (res.q <= lim[:, 1])).all()


@pytest.mark.parametrize("name", ARMS)
@pytest.mark.parametrize("kind", ["pose", "position"])
def test_round_trip_from_the_solution_neighbourhood(name, kind):
    model = load_model(name)
    rng = np.random.default_rng(2024)
    n = 4000
    q, q0 = neighbourhood(model, n, rng)
    T = model.fk(q)
    targets = T if kind == "pose" else T[:, :3, 3]
    res = solve_ik(model, targets, q0)
    assert res.tol_position == 1e-9 and (kind == "position" or res.tol_rotation == 1e-9)
    assert res.converged.mean() >= 0.999, res.summary()
    ok = res.converged
    assert res.position_error[ok].max() <= 1e-9
    if kind == "pose":
        assert res.rotation_error[ok].max() <= 1e-9
    else:
        assert np.isnan(res.rotation_error).all()
    check_reported_errors(model, res, targets)
    assert set(res.status) <= set(STATUS)
    assert (res.converged == np.isin(res.status, ["converged", "near-singular"])).all()
    if kind == "pose":  # 6 joints, 6 DOF: the seed's own solution (mod 2 pi) comes back, or
        # one at most as far from the seed (close to a singularity two solutions are close)
        regular = res.status == "converged"
        same = np.abs(np.angle(np.exp(1j * (res.q - q)))).max(axis=1) < 1e-6
        d_sol = np.linalg.norm(np.angle(np.exp(1j * (res.q - q0))), axis=1)
        d_orig = np.linalg.norm(q - q0, axis=1)
        assert np.mean(same[regular]) >= 0.98
        assert np.mean((same | (d_sol <= 1.1 * d_orig))[regular]) >= 0.995
    else:  # redundant: the step is minimum-norm, the answer no farther than the original
        d_sol = np.linalg.norm(res.q - q0, axis=1)[ok]
        d_orig = np.linalg.norm(q - q0, axis=1)[ok]
        assert np.median(d_sol / d_orig) < 1.0


@pytest.mark.parametrize("name", ARMS)
def test_unreachable_targets_are_flagged_never_converged(name):
    model = load_model(name)
    rng = np.random.default_rng(7)
    n = 200
    q, _ = neighbourhood(model, n, rng)
    T = model.fk(q)
    L = characteristic_length(model)
    d = rng.normal(size=(n, 3))
    far = d / np.linalg.norm(d, axis=1, keepdims=True) * L * rng.uniform(1.05, 3.0, (n, 1))
    Tfar = T.copy()
    Tfar[:, :3, 3] = far
    for targets in (far, Tfar):
        res = solve_ik(model, targets, q)
        assert not res.converged.any()
        assert (res.position_error > 0.04 * L).all()
        assert set(res.status) <= {"unreachable", "joint-limit", "max-iterations"}
        check_reported_errors(model, res, targets)


def test_orientation_a_four_joint_arm_cannot_reach_is_unreachable():
    # a SCARA-like arm: 3 revolute z joints and a prismatic z joint; it cannot tilt its tool
    joints = [dict(theta=0, d=400, a=300, alpha=0), dict(theta=0, d=0, a=250, alpha=0),
              dict(theta=0, d=0, a=0, alpha=0),
              dict(theta=0, d=0, a=0, alpha=0, type="prismatic")]
    lim = np.array([[-2.5, 2.5], [-2.5, 2.5], [-3.0, 3.0], [-200.0, 0.0]])
    model = SerialModel("scara", "dh", joints, tool=[0, 0, 50], joint_limits=lim)
    rng = np.random.default_rng(3)
    q, q0 = neighbourhood(model, 300, rng, sigma=0.05)
    T = model.fk(q)
    ok = solve_ik(model, T, q0)
    assert ok.converged.mean() >= 0.99
    tilted = T.copy()
    tilted[:, :3, :3] = matrix_from_axis_angle(np.tile([0.2, 0.0, 0.0], (300, 1))) @ T[:, :3, :3]
    bad = solve_ik(model, tilted, q0)
    assert not bad.converged.any()
    assert (bad.rotation_error > 0.1).all()
    # its position alone is reachable (4 joints for 3 DOF)
    pos = solve_ik(model, tilted[:, :3, 3], q0)
    assert pos.converged.mean() >= 0.99


def test_joint_limits_are_respected_and_reported():
    # planar two-link arm, elbow limited to [0, 2]: mirror (elbow-negative) targets cannot
    # be reached from their own branch and must not be reached by leaving the limits
    joints = [dict(theta=0, d=0, a=400, alpha=0), dict(theta=0, d=0, a=300, alpha=0)]
    lim = np.array([[-3.0, 3.0], [0.0, 2.0]])
    model = SerialModel("planar", "dh", joints, joint_limits=lim)
    rng = np.random.default_rng(5)
    q = np.column_stack([rng.uniform(-2, 2, 100), rng.uniform(0.3, 1.8, 100)])
    p = model.fk(q)[:, :3, 3]
    res = solve_ik(model, p, q + rng.normal(0, 0.05, q.shape))
    assert res.converged.all()
    # elbow-negative configurations within reach but beyond the elbow's lower limit; the
    # z coordinate is 0 (planar), the position target is reachable only with q2 < 0 ...
    q_bad = np.column_stack([rng.uniform(-2, 2, 100), rng.uniform(-1.8, -0.3, 100)])
    unlimited = SerialModel("planar", "dh", joints, joint_limits=[[-3, 3], [-3, 3]])
    T_bad = unlimited.fk(q_bad)  # ... with this orientation: the pose is unreachable
    res = solve_ik(model, T_bad, np.abs(q_bad))
    assert not res.converged.any()
    assert (res.q[:, 1] >= 0.0).all() and (res.q[:, 1] <= 2.0).all()
    assert (res.status == "joint-limit").mean() > 0.9


def test_full_turn_joints_wrap_instead_of_stopping_at_the_limit():
    model = load_model("hu2005-scanner")  # every joint +-180 deg
    rng = np.random.default_rng(9)
    q = random_configurations(model, 500, rng)
    q[:, 0] = np.pi - rng.uniform(0.0, 0.05, 500)  # solutions just inside +pi ...
    q0 = q.copy()
    q0[:, 0] = -np.pi + rng.uniform(0.0, 0.05, 500)  # ... seeds just inside -pi
    res = solve_ik(model, model.fk(q), q0)
    assert res.converged.mean() >= 0.999
    assert np.mean(np.abs(np.cos(res.q[:, 0] - q[:, 0]) - 1.0) < 1e-12) >= 0.99


def test_singular_configurations_converge_and_are_flagged():
    model = load_model("ur5")
    rng = np.random.default_rng(4)
    q = random_configurations(model, 200, rng)
    q[:, 4] = 0.0  # wrist singularity: axes 4 and 6 aligned
    res = solve_ik(model, model.fk(q), q + rng.normal(0, 0.01, q.shape))
    assert res.converged.mean() >= 0.99
    assert (res.status[res.converged] == "near-singular").all()
    assert (res.condition[res.converged] > 1e3).all()
    regular = solve_ik(model, model.fk(random_configurations(model, 200, rng)))
    assert np.median(regular.condition) < 1e3


@pytest.mark.parametrize("convention", ["dh", "craig", "hayati", "urdf"])
def test_every_convention_with_prismatic_joints_fixed_frames_base_and_tool(convention):
    rng = np.random.default_rng(12)
    model = _extended_model(convention, rng)
    params = model.nominal + rng.normal(0, 1e-3, model.n_params)  # a "calibrated" model
    q, q0 = neighbourhood(model, 1000, rng, sigma=0.05)
    q0 = np.clip(q0, model.joint_limits[:, 0], model.joint_limits[:, 1])
    T = model.fk(q, params)
    for targets in (T, T[:, :3, 3]):
        res = solve_ik(model, targets, q0, params=params)
        assert res.converged.mean() >= 0.99, res.summary()
        check_reported_errors(model, res, targets, params)
        tol = default_tol_position(model, params)
        assert res.position_error[res.converged].max() <= tol
    # the nominal model does not reach the calibrated model's poses at its joints
    assert solve_ik(model, T, q, max_iterations=1).position_error.min() > 0


def _extended_model(convention, rng):
    """Six joints (two prismatic) with fixed frames, a base frame and a tool frame."""
    frame_keys = ("roll", "pitch", "yaw") if convention == "urdf" else ("rx", "ry", "rz")

    def frame(name):
        f = {"frame": name, **{k: rng.uniform(-100, 100) for k in "xyz"}}
        f.update({k: rng.uniform(-0.5, 0.5) for k in frame_keys})
        return f

    if convention == "urdf":
        axes = [[0, 0, 1], [0, 1, 0], [0.3, -0.5, 0.81], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
        joints = []
        for i, axis in enumerate(axes):
            j = {"name": f"j{i + 1}", "type": "prismatic" if i in (2,) else "revolute",
                 "axis": axis, "offset": rng.uniform(-0.3, 0.3)}
            j.update({k: rng.uniform(50, 200) for k in "xyz"})
            j.update({k: rng.uniform(-0.5, 0.5) for k in ("roll", "pitch", "yaw")})
            joints.append(j)
        prismatic = [2]
    else:
        joints = []
        for i in range(6):
            j = dict(theta=rng.uniform(-1, 1), d=rng.uniform(-200, 200),
                     a=rng.uniform(50, 300), alpha=rng.uniform(-2, 2))
            if i in (1, 4):
                j["type"] = "prismatic"
            if convention == "hayati" and i in (1, 3):
                j["beta"] = rng.uniform(-0.05, 0.05)
            joints.append(j)
        prismatic = [1, 4]
    joints.insert(2, frame("bracket"))
    joints.append(frame("adapter"))
    lim = np.tile([-np.pi, np.pi], (6, 1))
    lim[prismatic] = [0.0, 300.0]
    base = np.r_[rng.uniform(-500, 500, 3), rng.uniform(-1, 1, 3)]
    tool = np.r_[rng.uniform(-50, 50, 3), rng.uniform(-1, 1, 3)]
    return SerialModel("ext", convention, joints, base=base, tool=tool, joint_limits=lim)


class JointCorrected:
    """A model that corrects its joint readings (q -> q + c sin q) inside fk and
    joint_jacobian, through nothing but the public API IK uses: IK must invert it."""

    def __init__(self, model, c):
        self.m, self.c = model, np.asarray(c)
        for name in ("n_joints", "n_params", "nominal", "parameter_names", "joint_limits",
                     "length_unit", "is_prismatic", "is_angle"):
            setattr(self, name, getattr(model, name))

    def fk(self, q, params=None):
        return self.m.fk(q + self.c * np.sin(q), params)

    def joint_jacobian(self, q, params=None, outputs="pose"):
        J = self.m.joint_jacobian(q + self.c * np.sin(q), params, outputs)
        return J * (1.0 + self.c * np.cos(q))[:, None, :]


def test_ik_inherits_joint_corrections_made_inside_fk_and_the_jacobian():
    base = load_model("irb120")
    model = JointCorrected(base, c=[0.01, -0.02, 0.015, 0.0, 0.01, -0.01])
    rng = np.random.default_rng(8)
    q, q0 = neighbourhood(base, 1000, rng, sigma=0.05)
    T = model.fk(q)
    res = solve_ik(model, T, q0)
    assert res.converged.mean() >= 0.999
    rot, pos = pose_errors(model.fk(res.q), T)
    assert pos[res.converged].max() <= 1e-9 and rot[res.converged].max() <= 1e-9
    # the uncorrected model at the same joints misses by millimetres
    assert np.median(pose_errors(base.fk(res.q), T)[1]) > 1.0


def test_restarts_recover_far_seeds_and_same_seed_gives_same_bits():
    model = load_model("kr6-craig")
    rng = np.random.default_rng(21)
    q = random_configurations(model, 150, rng)
    T = model.fk(q)
    # seeds anywhere: about half stop at a joint limit without restarts
    far = random_configurations(model, 150, rng)
    plain = solve_ik(model, T, far)
    a = solve_ik(model, T, far, restarts=20, rng=5)
    b = solve_ik(model, T, far, restarts=20, rng=5)
    assert plain.converged.mean() < 0.7
    assert a.converged.mean() >= 0.98
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.iterations, b.iterations)
    np.testing.assert_array_equal(a.status, b.status)
    assert (a.restarts[plain.converged] == 0).all()  # converged targets are not restarted
    np.testing.assert_array_equal(a.q[plain.converged], plain.q[plain.converged])


def test_result_summary_and_counts():
    model = load_model("ur5")
    rng = np.random.default_rng(1)
    q, q0 = neighbourhood(model, 50, rng)
    T = model.fk(q)
    T[0, :3, 3] = [5000.0, 0.0, 0.0]
    res = solve_ik(model, T, q0)
    assert len(res) == 50 and sum(res.counts().values()) == 50
    assert not res.converged[0]
    text = res.summary()
    assert "of 50 pose targets converged" in text and "mm" in text
    assert res.success_rate == res.converged.mean()


def test_bad_input_raises_input_error():
    model = load_model("ur5")
    q = np.zeros((2, 6))
    T = model.fk(q + 0.3)
    with pytest.raises(InputError, match="targets"):
        solve_ik(model, np.zeros((2, 4)), q)
    with pytest.raises(InputError, match="NaN"):
        solve_ik(model, np.full((2, 3), np.nan), q)
    with pytest.raises(InputError, match="q0"):
        solve_ik(model, T, np.zeros((3, 6)))
    with pytest.raises(InputError, match="q0"):
        solve_ik(model, T, np.full((2, 6), np.inf))
    bent = T.copy()
    bent[0, 0, 0] = 2.0
    with pytest.raises(InputError):
        solve_ik(model, bent, q)
    with pytest.raises(InputError, match="params"):
        solve_ik(model, T, q, params=np.zeros(3))
    for kw in ({"tol_position": 0.0}, {"tol_rotation": -1.0}, {"max_iterations": 0},
               {"restarts": -1}, {"rotation_weight": 0.0}):
        with pytest.raises(InputError):
            solve_ik(model, T, q, **kw)
    # one target, one seed: shapes (3,) / (4, 4) and (n,) are accepted
    one = solve_ik(model, T[0], q[0] + 0.3)
    assert one.q.shape == (1, 6) and one.converged[0]


def test_redundant_urdf_arm_checked_by_pinocchio():
    """A 7-joint URDF arm (KUKA LBR iiwa 14 of rtb-data): pose targets are redundant; the
    answers are checked by an independent forward kinematics (pinocchio) of the same URDF."""
    from importlib import resources

    import pinocchio as pin

    path = str(resources.files("rtbdata") / "xacro" / "kuka_description" / "kuka_lbr_iiwa"
               / "urdf" / "lbr_iiwa_14_r820.urdf")
    model = load_model(path)
    assert model.n_joints == 7 and model.length_unit == "m"
    rng = np.random.default_rng(17)
    q, q0 = neighbourhood(model, 1000, rng)
    q0 = np.clip(q0, model.joint_limits[:, 0], model.joint_limits[:, 1])
    T = model.fk(q)
    res = solve_ik(model, T, q0)
    assert res.tol_position == 1e-12  # 1e-9 mm in metres
    assert res.converged.mean() >= 0.999
    pm = pin.buildModelFromUrdf(path)
    data = pm.createData()
    frame = pm.getFrameId("tool0")
    for k in np.flatnonzero(res.converged)[:200]:
        pin.framesForwardKinematics(pm, data, res.q[k])
        M = data.oMf[frame]
        np.testing.assert_allclose(M.translation, T[k, :3, 3], atol=1e-11)
        np.testing.assert_allclose(M.rotation, T[k, :3, :3], atol=1e-9)
    # redundancy: the minimum-norm steps end no farther from the seed than the original
    d_sol = np.linalg.norm(res.q - q0, axis=1)[res.converged]
    d_orig = np.linalg.norm(q - q0, axis=1)[res.converged]
    assert np.median(d_sol / d_orig) <= 1.0


class FkOnly:
    """A model exposing only fk and joint_jacobian (no sweep)."""

    def __init__(self, model):
        self.m = model
        for name in ("n_joints", "n_params", "nominal", "parameter_names", "joint_limits",
                     "length_unit", "is_prismatic", "is_angle", "fk", "joint_jacobian"):
            setattr(self, name, getattr(model, name))


def test_sweep_path_and_fk_jacobian_path_give_the_same_bits():
    model = load_model("kr6-craig")
    rng = np.random.default_rng(30)
    q, q0 = neighbourhood(model, 500, rng)
    T = model.fk(q)
    for targets in (T, T[:, :3, 3]):
        a = solve_ik(model, targets, q0)
        b = solve_ik(FkOnly(model), targets, q0)
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.status, b.status)
        np.testing.assert_array_equal(a.iterations, b.iterations)
    # and a target's answer does not depend on the other targets of the batch; one target
    # alone takes the folded single-pose chain: the same answer to round-off
    full = solve_ik(model, T, q0)
    two = solve_ik(model, T[7:9], q0[7:9])
    np.testing.assert_array_equal(two.q, full.q[7:9])
    one = solve_ik(model, T[7:8], q0[7:8])
    np.testing.assert_allclose(one.q[0], full.q[7], rtol=0, atol=1e-12)
    assert one.status[0] == full.status[7]
