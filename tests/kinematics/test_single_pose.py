"""One configuration at a time (`kinecal.kinematics.serial.single`): the folded chain gives
the batch path's poses and joint Jacobians to round-off on every convention, with base and
tool frames, fixed frames, prismatic joints and general (URDF) axes, for the nominal and
for a calibrated parameter vector; models it does not cover take the batch path."""

import numpy as np
import pytest

from kinecal.io.models import load_model
from kinecal.kinematics.serial.ik import solve_ik
from kinecal.kinematics.serial.model import SerialModel


def _frame(rng, name, keys=("rx", "ry", "rz")):
    return {"frame": name, **{k: rng.uniform(-100, 100) for k in "xyz"},
            **{k: rng.uniform(-1, 1) for k in keys}}


def _dh_family(convention, rng):
    """Joints 2 and 5 prismatic, fixed frames at the start and in the middle, base and
    tool frames."""
    joints = [dict(theta=rng.uniform(-1, 1), d=rng.uniform(-200, 200), a=rng.uniform(-200, 200),
                   alpha=rng.uniform(-2, 2), **({"type": "prismatic"} if i in (1, 4) else {}),
                   **({"beta": 0.03} if convention == "hayati" and i == 1 else {}))
              for i in range(6)]
    joints.insert(0, _frame(rng, "mount"))
    joints.insert(4, _frame(rng, "bracket"))
    limits = np.tile([-np.pi, np.pi], (6, 1))
    limits[[1, 4]] = [[-50, 300], [0, 120]]
    return SerialModel("ext", convention, joints, base=np.r_[rng.uniform(-500, 500, 3),
                                                            rng.uniform(-1, 1, 3)],
                       tool=np.r_[rng.uniform(-50, 50, 3), rng.uniform(-1, 1, 3)],
                       joint_limits=limits)


def _urdf(rng):
    """General, negative and elementary axes, one prismatic joint, a fixed frame."""
    axes = [[0, 0, 1], [0, -1, 0], [0.3, -0.5, 0.81], [1, 0, 0], [-0.2, 0.9, 0.1], [0, 0, -1]]
    joints = [{"name": f"j{i + 1}", "type": "prismatic" if i == 2 else "revolute", "axis": a,
               "offset": rng.uniform(-0.5, 0.5), **{k: rng.uniform(-0.3, 0.3) for k in "xyz"},
               **{k: rng.uniform(-1, 1) for k in ("roll", "pitch", "yaw")}}
              for i, a in enumerate(axes)]
    joints.insert(3, _frame(rng, "fixed", keys=("roll", "pitch", "yaw")))
    limits = np.tile([-np.pi, np.pi], (6, 1))
    limits[2] = [0.0, 0.4]
    return SerialModel("u", "urdf", joints, base=np.r_[rng.uniform(-1, 1, 6)],
                       tool=[0.01, 0.02, 0.1], length_unit="m", joint_limits=limits)


def _models():
    rng = np.random.default_rng(5)
    return [load_model("ur5"), load_model("irb120"), load_model("kr6-craig"),
            load_model("puma560"), _dh_family("dh", rng), _dh_family("craig", rng),
            _dh_family("hayati", rng), _urdf(rng)]


@pytest.mark.parametrize("model", _models(), ids=lambda m: f"{m.name}-{m.convention}")
def test_folded_chain_matches_the_batch_path(model):
    rng = np.random.default_rng(1)
    lim = np.asarray(model.joint_limits)
    q = rng.uniform(lim[:, 0], lim[:, 1], (5, model.n_joints))
    calibrated = model.nominal + rng.normal(0, 1e-3, model.n_params)
    scale = max(1.0, float(np.abs(model.fk(q)[:, :3, 3]).max()))
    for params in (None, calibrated, calibrated):  # a vector is folded once seen twice
        batch = model.fk(q, params)  # (5, n): the batch path
        Jb = model.joint_jacobian(q, params)
        for k in range(len(q)):
            one = model.fk(q[k], params)  # (n_joints,): the folded chain
            assert one.shape == (1, 4, 4)
            np.testing.assert_allclose(one[0, :3, :3], batch[k, :3, :3], rtol=0, atol=1e-12)
            np.testing.assert_allclose(one[0, :3, 3], batch[k, :3, 3], rtol=0,
                                       atol=1e-12 * scale)
            np.testing.assert_allclose(model.positions(q[k], params)[0], batch[k, :3, 3],
                                       rtol=0, atol=1e-12 * scale)
            got = model.single_pose(q[k], params)
            if params is None or got is not None:
                T, J = got
                np.testing.assert_allclose(T, batch[k], rtol=0, atol=1e-12 * scale)
                np.testing.assert_allclose(J, Jb[k], rtol=0, atol=1e-12 * scale)
    # a batch of one keeps the batch path's bits
    np.testing.assert_array_equal(model.fk(q[:1]), model.fk(q)[:1])


def test_models_the_fold_does_not_cover_take_the_batch_path():
    ur5 = load_model("ur5")
    markers = ur5.with_markers({"a": [0.0, 0.0, 10.0], "b": [5.0, 0.0, 30.0]})
    q = np.full(6, 0.3)
    assert markers.single_pose(q) is None
    np.testing.assert_array_equal(markers.fk(q, marker=[1]), markers.fk(q[None], marker=[1]))
    new = ur5.nominal + 1e-3
    assert ur5.single_pose(q, new) is None  # first sight of a vector: nothing built
    assert ur5.single_pose(q, new) is not None
    with pytest.raises(Exception, match="NaN or infinite"):
        ur5.fk(np.r_[q[:5], np.nan])


def test_one_target_inverse_kinematics_matches_the_batch():
    model = load_model("irb120")
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (4, model.n_joints))
    q0 = q + rng.normal(0, 0.05, q.shape)
    T = model.fk(q)
    batch = solve_ik(model, T, q0)
    for k in range(len(q)):
        one = solve_ik(model, T[k], q0[k])
        np.testing.assert_allclose(one.q[0], batch.q[k], rtol=0, atol=1e-12)
        assert one.status[0] == batch.status[k] and one.converged[0]


@pytest.mark.parametrize("model", _models(), ids=lambda m: f"{m.name}-{m.convention}")
def test_one_target_on_floats_matches_the_batch_on_every_chain(model):
    """`kinecal.kinematics.serial.ik_one`: prismatic joints (scaled columns), general URDF
    axes, joints that clip at a limit and joints that wrap, pose and position targets."""
    rng = np.random.default_rng(11)
    lim = np.asarray(model.joint_limits)
    mid, half = lim.mean(axis=1), 0.4 * (lim[:, 1] - lim[:, 0])
    q = rng.uniform(mid - half, mid + half, (6, model.n_joints))
    q0 = q + rng.normal(0, 0.05, q.shape) * (lim[:, 1] - lim[:, 0]) / (2 * np.pi)
    q0[0] = lim[:, 1]  # a seed at the upper limits: steps outward are frozen there
    T = model.fk(q)
    for targets in (T, T[:, :3, 3]):
        batch = solve_ik(model, targets, q0)
        for k in range(len(q)):
            one = solve_ik(model, targets[k], q0[k])
            scale = max(1.0, float(np.abs(targets[k]).max()))
            np.testing.assert_allclose(one.q[0], batch.q[k], rtol=0, atol=1e-11 * scale)
            assert one.status[0] == batch.status[k]
            assert one.converged[0] == batch.converged[k]
            np.testing.assert_allclose(one.condition[0], batch.condition[k], rtol=1e-6)
