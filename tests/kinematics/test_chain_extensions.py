"""Prismatic joints, fixed frames and the urdf convention: formulas, analytic Jacobians
against finite differences, joint units, model files."""

import numpy as np
import pytest

from kinecal.calibration.serial.simulate import random_configurations
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.io.measurements import read_joints, read_measurements, write_measurements
from kinecal.io.models import load_model, save_model
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import (
    axis_angle_from_matrix,
    matrix_from_axis_angle,
    rot_x,
    rot_z,
    transform_from,
    transform_from_xyz_rpy,
)


def _frame(rng, name, calibrate=False, keys=("rx", "ry", "rz")):
    f = {"frame": name, "x": rng.uniform(-100, 100), "y": rng.uniform(-100, 100),
         "z": rng.uniform(-100, 100)}
    f.update({k: rng.uniform(-1, 1) for k in keys})
    if calibrate:
        f["calibrate"] = True
    return f


def dh_family_model(convention, rng):
    """Six joints (2 and 5 prismatic) with fixed frames at the start, middle and end."""
    joints = []
    for i in range(6):
        j = dict(theta=rng.uniform(-1, 1), d=rng.uniform(-200, 200), a=rng.uniform(-200, 200),
                 alpha=rng.uniform(-2, 2))
        if i in (1, 4):
            j["type"] = "prismatic"
        if convention == "hayati" and i in (1, 3):
            j["beta"] = rng.uniform(-0.05, 0.05)
        joints.append(j)
    joints.insert(0, _frame(rng, "mount"))
    joints.insert(4, _frame(rng, "bracket", calibrate=True))
    joints.append(_frame(rng, "flange_adapter"))
    limits = np.tile([-np.pi, np.pi], (6, 1))
    limits[[1, 4]] = [[-50, 300], [0, 120]]
    base = np.r_[rng.uniform(-500, 500, 3), rng.uniform(-1, 1, 3)]
    tool = np.r_[rng.uniform(-50, 50, 3), rng.uniform(-1, 1, 3)]
    return SerialModel("ext", convention, joints, base=base, tool=tool, joint_limits=limits)


def urdf_model(rng):
    """URDF joints with general, negative and elementary axes, one prismatic, fixed frames."""
    axes = [[0, 0, 1], [0, -1, 0], [0.3, -0.5, 0.81], [1, 0, 0], [-0.2, 0.9, 0.1], [0, 0, -1]]
    joints = []
    for i, axis in enumerate(axes):
        j = {"name": f"j{i + 1}", "type": "prismatic" if i == 2 else "revolute",
             "axis": axis, "offset": rng.uniform(-0.5, 0.5)}
        j.update({k: rng.uniform(-0.3, 0.3) for k in ("x", "y", "z")})
        j.update({k: rng.uniform(-1, 1) for k in ("roll", "pitch", "yaw")})
        joints.append(j)
    joints.insert(3, _frame(rng, "j3-fixed", keys=("roll", "pitch", "yaw")))
    joints.append(_frame(rng, "j6-tool0", calibrate=True, keys=("roll", "pitch", "yaw")))
    limits = np.tile([-np.pi, np.pi], (6, 1))
    limits[2] = [0.0, 0.4]
    base = np.r_[rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)]
    return SerialModel("u", "urdf", joints, base=base, tool=[0.01, 0.02, 0.1],
                       length_unit="m", joint_limits=limits)


def numerical_jacobian(model, q, p, h=1e-6):
    J = np.zeros((q.shape[0], 6, model.n_params))
    for k in range(model.n_params):
        dp = np.zeros(model.n_params)
        dp[k] = h
        Tp, Tm = model.fk(q, p + dp), model.fk(q, p - dp)
        J[:, :3, k] = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)
        dR = Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2)
        J[:, 3:, k] = axis_angle_from_matrix(dR) / (2 * h)
    return J


MODELS = {
    "dh": lambda rng: dh_family_model("dh", rng),
    "craig": lambda rng: dh_family_model("craig", rng),
    "hayati": lambda rng: dh_family_model("hayati", rng),
    "urdf": urdf_model,
}


@pytest.mark.parametrize("convention", list(MODELS))
def test_identification_and_joint_jacobians_match_finite_differences(convention):
    rng = np.random.default_rng(11)
    model = MODELS[convention](rng)
    q = random_configurations(model, 6, rng)
    p = model.nominal + rng.normal(0, 0.01, model.n_params)
    J = model.identification_jacobian(q, p, outputs="pose")
    Jn = numerical_jacobian(model, q, p)
    scale = np.maximum(np.abs(Jn).max(axis=(0, 1)), 1e-12)
    rel = np.abs(J - Jn).max(axis=(0, 1)) / scale
    assert rel.max() < 1e-6, dict(zip(model.parameter_names, rel, strict=True))
    # every parameter moves the tool (none dropped, none dead) except zero-effect ones
    assert np.abs(Jn).max(axis=(0, 1)).min() > 0
    Jq = model.joint_jacobian(q, p)
    h = 1e-6
    for j in range(model.n_joints):
        dq = np.zeros(model.n_joints)
        dq[j] = h
        Tp, Tm = model.fk(q + dq, p), model.fk(q - dq, p)
        np.testing.assert_allclose(Jq[:, :3, j], (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h),
                                   atol=1e-6 * np.abs(Jq[:, :3]).max())
        dR = Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2)
        np.testing.assert_allclose(Jq[:, 3:, j], axis_angle_from_matrix(dR) / (2 * h),
                                   atol=1e-7)
    # a prismatic joint translates the tool along its axis and does not turn it
    for j in np.flatnonzero(model.is_prismatic()):
        np.testing.assert_allclose(np.linalg.norm(Jq[:, :3, j], axis=1), 1.0, atol=1e-12)
        np.testing.assert_array_equal(Jq[:, 3:, j], 0.0)


@pytest.mark.parametrize("convention", list(MODELS))
def test_population_fk_equals_one_by_one(convention):
    rng = np.random.default_rng(12)
    model = MODELS[convention](rng)
    q = random_configurations(model, 9, rng)
    P = model.nominal + rng.normal(0, 0.01, (4, model.n_params))
    T = model.fk(q, P)
    for k in range(4):
        np.testing.assert_allclose(T[k], model.fk(q, P[k]), rtol=0, atol=1e-12)


def test_prismatic_dh_joint_moves_d():
    th, d, a, al, q = 0.3, 20.0, 15.0, -0.7, 42.0
    model = SerialModel("p", "dh", [dict(theta=th, d=d, a=a, alpha=al, type="prismatic")],
                        joint_limits=[[0, 100]])
    T = model.fk([[q]])[0]
    expected = (transform_from(rot_z(th), [0, 0, 0]) @ transform_from(np.eye(3), [0, 0, d + q])
                @ transform_from(rot_x(al), [a, 0, 0]))
    np.testing.assert_allclose(T, expected, atol=1e-12)
    assert model.joint_kinds == ("prismatic",)
    assert not model.is_angle()[model.index(["d1"])[0]]
    assert model.is_angle()[model.index(["theta1"])[0]]


def test_urdf_joint_is_origin_then_axis_motion():
    rng = np.random.default_rng(3)
    xyz, rpy = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)
    axis = np.array([0.2, -0.4, 0.7])
    u = axis / np.linalg.norm(axis)
    q, off = 0.9, 0.1
    joint = dict(name="j", x=xyz[0], y=xyz[1], z=xyz[2], roll=rpy[0], pitch=rpy[1], yaw=rpy[2],
                 axis=axis.tolist(), offset=off)
    origin = transform_from_xyz_rpy(np.r_[xyz, rpy])
    rev = SerialModel("r", "urdf", [joint]).fk([[q]])[0]
    np.testing.assert_allclose(rev, origin @ transform_from(matrix_from_axis_angle(u * (q + off)),
                                                             [0, 0, 0]), atol=1e-12)
    pri = SerialModel("p", "urdf", [{**joint, "type": "prismatic"}],
                      joint_limits=[[0, 1]]).fk([[q]])[0]
    np.testing.assert_allclose(pri, origin @ transform_from(np.eye(3), u * (q + off)), atol=1e-12)
    model = SerialModel("r", "urdf", [joint])
    assert model.parameter_names[:10] == ("j.x", "j.y", "j.z", "j.yaw", "j.pitch", "j.roll",
                                          "j.wz", "j.wy", "j.wx", "j.offset")
    # the nominal roll-pitch-yaw is held; its error is the local rotation wx, wy, wz
    assert {"j.roll", "j.pitch", "j.yaw"} <= model.fixed_names
    assert {"j.wx", "j.wy", "j.wz", "j.x", "j.offset"} <= set(model.calibratable)
    w = rng.uniform(-0.3, 0.3, 3)
    moved = SerialModel("w", "urdf", [{**joint, "wx": w[0], "wy": w[1], "wz": w[2]}])
    np.testing.assert_allclose(
        moved.fk([[q]])[0], origin @ transform_from_xyz_rpy(np.r_[0, 0, 0, w])
        @ transform_from(matrix_from_axis_angle(u * (q + off)), [0, 0, 0]), atol=1e-12)


def test_fixed_frames_compose_and_are_fixed_by_default():
    rng = np.random.default_rng(5)
    j1, j2 = dict(theta=0.1, d=100, a=10, alpha=0.5), dict(theta=0, d=0, a=300, alpha=0)
    mount = {"frame": "mount", "x": 10.0, "y": -20.0, "z": 500.0, "rx": 0.1, "ry": 0.2,
             "rz": 1.5}
    bare1 = SerialModel("a", "dh", [j1])
    bare2 = SerialModel("b", "dh", [j2])
    both = SerialModel("m", "dh", [j1, mount, j2])
    q = rng.uniform(-3, 3, (5, 2))
    M = transform_from_xyz_rpy([10, -20, 500, 0.1, 0.2, 1.5])
    np.testing.assert_allclose(both.fk(q), bare1.fk(q[:, :1]) @ M @ bare2.fk(q[:, 1:]),
                               atol=1e-9)
    assert both.n_joints == 2
    names = [f"mount.{k}" for k in ("x", "y", "z", "rx", "ry", "rz")]
    assert set(names) <= set(both.parameter_names)
    assert not set(names) & set(both.calibratable)
    freed = SerialModel("m", "dh", [j1, {**mount, "calibrate": True}, j2])
    local = [f"mount.{k}" for k in ("x", "y", "z", "wx", "wy", "wz")]
    assert set(local) <= set(freed.calibratable)  # its rotation error is local
    assert {"mount.rx", "mount.ry", "mount.rz"} <= freed.fixed_names
    zero = SerialModel("m", "dh", [j1, {"frame": "mount"}, j2])
    assert set(names) <= set(zero.parameter_names)  # zero-valued parameters are kept


def test_joint_units_per_kind_in_files_and_sampling(tmp_path):
    rng = np.random.default_rng(2)
    model = dh_family_model("dh", rng)
    model.angle_unit = "deg"
    np.testing.assert_allclose(model.joint_scale(), [np.pi / 180, 1, np.pi / 180,
                                                     np.pi / 180, 1, np.pi / 180])
    q = random_configurations(model, 400, rng)
    assert q[:, 1].min() >= -50 and q[:, 1].max() > 200  # prismatic range not clipped to pi
    assert q[:, 4].min() >= 0 and q[:, 4].max() > 100
    data = Measurements(q, model.positions(q))
    write_measurements(tmp_path / "m.csv", data, model)
    header = (tmp_path / "m.csv").read_text().splitlines()[0].split(",")
    raw = np.loadtxt(tmp_path / "m.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(raw[:, header.index("q2")], q[:, 1])  # length unit
    np.testing.assert_allclose(raw[:, header.index("q1")], np.rad2deg(q[:, 0]))
    back = read_measurements(tmp_path / "m.csv", model)
    np.testing.assert_allclose(back.q, q, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(read_joints(tmp_path / "m.csv", model), q, rtol=1e-12,
                               atol=1e-12)


@pytest.mark.parametrize("convention", list(MODELS))
def test_model_file_round_trip(tmp_path, convention):
    rng = np.random.default_rng(8)
    model = MODELS[convention](rng)
    model.angle_unit = "deg"
    save_model(model, tmp_path / "m.yaml")
    back = load_model(tmp_path / "m.yaml")
    assert back.parameter_names == model.parameter_names
    assert back.calibratable == model.calibratable
    assert back.joint_kinds == model.joint_kinds
    np.testing.assert_allclose(back.nominal, model.nominal, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(back.joint_limits, model.joint_limits, rtol=1e-14)
    q = random_configurations(model, 5, rng)
    np.testing.assert_allclose(back.fk(q), model.fk(q), atol=1e-9)
    p = model.nominal + rng.normal(0, 0.01, model.n_params)
    changed = model.with_params(p)
    assert changed.calibratable == model.calibratable
    np.testing.assert_allclose(changed.fk(q), model.fk(q, p), atol=1e-9)


def test_model_file_with_prismatic_joint_and_frames(tmp_path):
    path = tmp_path / "gantry.yaml"
    path.write_text(
        "name: gantry\nconvention: dh\nlength_unit: mm\nangle_unit: deg\njoints:\n"
        "  - {frame: mount, z: 800, rz: 90}\n"
        "  - {theta: 0, d: 0, a: 0, alpha: -90, type: prismatic}\n"
        "  - {theta: 0, d: 100, a: 250, alpha: 0}\n"
        "joint_limits: [[0, 500], [-170, 170]]\n")
    m = load_model(path)
    assert m.joint_kinds == ("prismatic", "revolute")
    np.testing.assert_allclose(m.joint_limits, [[0, 500], np.deg2rad([-170, 170])])
    assert "mount.rz" in m.fixed_names
    np.testing.assert_allclose(m.nominal[m.index(["mount.rz"])], np.pi / 2)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(joints=[dict(theta=0, d=0, a=0, alpha=0, type="prismatic")]), "need limits"),
        (dict(joints=[dict(theta=0, d=0, a=0, alpha=0, type="spherical")]), "spherical"),
        (dict(joints=[{"frame": "base"}, dict(theta=0, d=0, a=0, alpha=0)]), "reserved"),
        (dict(joints=[{"frame": "f"}, {"frame": "f"}, dict(theta=0, d=0, a=0, alpha=0)]),
         "twice"),
        (dict(joints=[{"frame": "f"}]), "moving joint"),
        (dict(joints=[{"frame": "a,b"}, dict(theta=0, d=0, a=0, alpha=0)]), "commas"),
        (dict(joints=[{"frame": " a"}, dict(theta=0, d=0, a=0, alpha=0)]), "either end"),
        (dict(joints=[{"frame": "a\nb"}, dict(theta=0, d=0, a=0, alpha=0)]), "control"),
        (dict(joints=[dict(theta=0, d=np.nan, a=0, alpha=0)]), "finite"),
    ],
)
def test_bad_chains_raise_input_error(kwargs, match):
    with pytest.raises(InputError, match=match):
        SerialModel("x", "dh", **kwargs)


@pytest.mark.parametrize(
    ("joint", "match"),
    [({"axis": [0, 0, 1]}, "name"), ({"name": "j", "axis": [0, 0, 0]}, "non-zero"),
     ({"name": "j", "type": "floating"}, "floating")],
)
def test_bad_urdf_joints(joint, match):
    with pytest.raises(InputError, match=match):
        SerialModel("x", "urdf", [joint])
