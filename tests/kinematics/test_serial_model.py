"""SerialModel: forward kinematics and the analytic identification Jacobian."""

import numpy as np
import pytest
from scipy.optimize import least_squares

import kinecal
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import (
    axis_angle_from_matrix,
    rot_x,
    rot_y,
    rot_z,
    transform_from,
    transform_from_xyz_rpy,
)


def random_model(convention, rng, tool_frame=True):
    joints = [
        dict(theta=rng.uniform(-1, 1), d=rng.uniform(-200, 200), a=rng.uniform(-200, 200),
             alpha=rng.uniform(-2, 2))
        for _ in range(6)
    ]
    if convention == "hayati":
        joints[1]["beta"] = rng.uniform(-0.05, 0.05)
        joints[3]["beta"] = rng.uniform(-0.05, 0.05)
    tool = np.r_[rng.uniform(-50, 50, 3), rng.uniform(-1, 1, 3)] if tool_frame else [1, 2, 90]
    base = np.r_[rng.uniform(-500, 500, 3), rng.uniform(-1, 1, 3)]
    return SerialModel("random", convention, joints, base=base, tool=tool)


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


@pytest.mark.parametrize("convention", ["dh", "craig", "hayati"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jacobian_matches_finite_differences(convention, seed):
    rng = np.random.default_rng(seed)
    model = random_model(convention, rng, tool_frame=seed != 1)
    q = rng.uniform(-np.pi, np.pi, (7, 6))
    p = model.nominal + rng.normal(0, 0.01, model.n_params)
    J = model.identification_jacobian(q, p, outputs="pose")
    Jn = numerical_jacobian(model, q, p)
    scale = np.abs(Jn).max(axis=(0, 1))  # per-parameter column scale
    rel = np.abs(J - Jn).max(axis=(0, 1)) / scale
    assert rel.max() < 1e-6, dict(zip(model.parameter_names, rel, strict=True))
    Jp = model.identification_jacobian(q, p, outputs="position")
    np.testing.assert_array_equal(Jp, J[:, :3])


def test_every_parameter_is_kept_even_when_zero():
    model = kinecal.load_model("hu2005-scanner")
    names = model.parameter_names
    for i in range(1, 7):
        for k in ("theta", "d", "a", "alpha"):
            assert f"{k}{i}" in names  # a_i are all zero nominally: never dropped
    assert len(model.calibratable) == 25
    assert "tool.z" in model.calibratable and "tool.x" not in model.calibratable


def test_dh_matches_paper000_eq2():
    # papers/000 eq. (2): the standard D-H link matrix written out.
    th, h, d, al = 0.7, 150.0, 12.0, -1.1
    model = SerialModel("one", "dh", [dict(theta=0.0, d=h, a=d, alpha=al)])
    T = model.fk([[th]])[0]
    c, s, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
    expected = np.array([[c, -s * ca, s * sa, d * c], [s, c * ca, -c * sa, d * s],
                         [0, sa, ca, h], [0, 0, 0, 1]])
    np.testing.assert_allclose(T, expected, atol=1e-12)


def test_conventions_match_their_formulas():
    rng = np.random.default_rng(5)
    th, d, a, al, be, q = rng.uniform(-1, 1, 6)
    tz = transform_from(np.eye(3), [0, 0, d])
    tx = transform_from(np.eye(3), [a, 0, 0])

    def R(M):
        return transform_from(M, [0, 0, 0])

    craig = SerialModel("c", "craig", [dict(theta=th, d=d, a=a, alpha=al)]).fk([[q]])[0]
    np.testing.assert_allclose(craig, R(rot_x(al)) @ tx @ R(rot_z(th + q)) @ tz, atol=1e-12)
    hay = SerialModel("h", "hayati", [dict(theta=th, d=d, a=a, alpha=al, beta=be)]).fk([[q]])[0]
    np.testing.assert_allclose(
        hay, R(rot_z(th + q)) @ tz @ tx @ R(rot_x(al)) @ R(rot_y(be)), atol=1e-12
    )


def test_base_and_tool_frames():
    rng = np.random.default_rng(3)
    base = np.r_[rng.uniform(-100, 100, 3), rng.uniform(-1, 1, 3)]
    tool = np.r_[rng.uniform(-100, 100, 3), rng.uniform(-1, 1, 3)]
    joints = [dict(theta=0.1, d=100, a=10, alpha=0.5), dict(theta=0, d=0, a=300, alpha=0)]
    bare = SerialModel("bare", "dh", joints)
    full = SerialModel("full", "dh", joints, base=base, tool=tool)
    q = rng.uniform(-3, 3, (4, 2))
    expected = transform_from_xyz_rpy(base) @ bare.fk(q) @ transform_from_xyz_rpy(tool)
    np.testing.assert_allclose(full.fk(q), expected, atol=1e-9)


def test_population_fk_equals_one_by_one():
    rng = np.random.default_rng(4)
    model = random_model("hayati", rng)
    q = rng.uniform(-3, 3, (11, 6))
    P = model.nominal + rng.normal(0, 0.01, (5, model.n_params))
    T = model.fk(q, P)
    assert T.shape == (5, 11, 4, 4)
    for k in range(5):
        np.testing.assert_array_equal(T[k], model.fk(q, P[k]))
        np.testing.assert_array_equal(model.positions(q, P)[k], model.positions(q, P[k]))
    # positions are composed from the tool point backwards, frames forwards: same to round-off
    np.testing.assert_allclose(model.positions(q, P), T[..., :3, 3], rtol=1e-13, atol=1e-12)


def test_ur5_reproduces_dataset_targets():
    """FK of the catalogue UR5 reproduces the dataset's target columns (base frame fitted)."""
    model = kinecal.load_model("ur5")
    from kinecal.datasets import bundled_csv

    d = np.genfromtxt(bundled_csv("ur5-laser-tracker:grid"), delimiter=",", names=True)
    q = np.deg2rad(np.column_stack([d[f"joint_{i}"] for i in range(1, 7)]))
    target = np.column_stack([d["x_t"], d["y_t"], d["z_t"]])
    rms0 = np.sqrt(((model.positions(q) - target) ** 2).sum(1).mean())
    assert rms0 < 0.03  # catalogue values and tool point alone: 0.024 mm rms
    idx = model.index([*(f"base.{k}" for k in ("x", "y", "z", "rx", "ry", "rz"))])

    def residual(x):
        p = model.nominal
        p[idx] = x
        return (model.positions(q, p) - target).ravel()

    def jac(x):
        p = model.nominal
        p[idx] = x
        return model.identification_jacobian(q, p)[:, :, idx].reshape(-1, idx.size)

    fit = least_squares(residual, model.nominal[idx], jac=jac, method="lm")
    rms = np.sqrt((fit.fun.reshape(-1, 3) ** 2).sum(1).mean())
    assert rms <= 0.02


def test_bad_inputs_raise_input_error():
    model = kinecal.load_model("irb120")
    with pytest.raises(InputError, match=r"\(N, 6\)"):
        model.fk(np.zeros((3, 5)))
    with pytest.raises(InputError, match="NaN"):
        model.fk(np.full((1, 6), np.nan))
    with pytest.raises(InputError, match="parameters"):
        model.fk(np.zeros((1, 6)), np.zeros(3))
    with pytest.raises(InputError, match="unknown parameter"):
        model.index(["theta9"])
    with pytest.raises(InputError, match="convention"):
        SerialModel("x", "dhx", [dict(theta=0, d=0, a=0, alpha=0)])
    with pytest.raises(InputError, match="beta"):
        SerialModel("x", "dh", [dict(theta=0, d=0, a=0, alpha=0, beta=0)])


@pytest.mark.parametrize("convention", ["dh", "craig", "hayati"])
def test_joint_jacobian_matches_finite_differences(convention):
    rng = np.random.default_rng(7)
    model = random_model(convention, rng)
    q = rng.uniform(-np.pi, np.pi, (5, 6))
    p = model.nominal + rng.normal(0, 0.01, model.n_params)
    J = model.joint_jacobian(q, p)
    h = 1e-6
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        Tp, Tm = model.fk(q + dq, p), model.fk(q - dq, p)
        np.testing.assert_allclose(J[:, :3, j], (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h),
                                   atol=1e-6 * np.abs(J[:, :3]).max())
        dR = Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2)
        np.testing.assert_allclose(J[:, 3:, j], axis_angle_from_matrix(dR) / (2 * h), atol=1e-7)
    np.testing.assert_array_equal(model.joint_jacobian(q, p, outputs="position"), J[:, :3])
