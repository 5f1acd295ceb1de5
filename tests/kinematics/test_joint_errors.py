"""Joint-error corrections: compliance, harmonics, scale; their Jacobians and the hook."""

import dataclasses

import numpy as np
import pytest

import kinecal
from kinecal.errors import InputError
from kinecal.kinematics.serial.joint_errors import JointErrors, PointMass, joint_errors_for
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import axis_angle_from_matrix

GRAVITY = (0.1, 0.2, -1.0)


def random_chain(convention, rng, prismatic=False):
    """Six joints (one prismatic if asked), a fixed frame, base and tool frame."""
    if convention == "urdf":
        joints = [dict(name=f"j{i}", x=rng.uniform(-100, 100), y=rng.uniform(-100, 100),
                       z=rng.uniform(0, 200), roll=rng.uniform(-1, 1),
                       pitch=rng.uniform(-1, 1), yaw=rng.uniform(-1, 1),
                       axis=list(rng.normal(size=3)), type="revolute") for i in range(6)]
        joints.insert(3, dict(frame="bracket", x=10.0, y=-5.0, z=20.0, roll=0.1))
    else:
        joints = [dict(theta=rng.uniform(-1, 1), d=rng.uniform(-200, 200),
                       a=rng.uniform(-200, 200), alpha=rng.uniform(-2, 2)) for _ in range(6)]
        joints.insert(2, dict(frame="bracket", x=10.0, y=-5.0, z=20.0, rz=0.3))
        if convention == "hayati":
            joints[1]["beta"] = 0.01
    limits = None
    if prismatic:
        joints[4]["type"] = "prismatic"
        limits = [[-np.pi, np.pi]] * 6
        limits[3] = [0.0, 300.0]
    tool = np.r_[rng.uniform(-50, 50, 3), rng.uniform(-1, 1, 3)]
    base = np.r_[rng.uniform(-500, 500, 3), rng.uniform(-1, 1, 3)]
    return SerialModel("random", convention, joints, base=base, tool=tool,
                       joint_limits=limits)


def with_terms(model, masses=None, harmonics=2, gravity=GRAVITY):
    spec = joint_errors_for(model, ["compliance", "harmonic", "scale"], harmonics)
    payload = PointMass(model.n_joints, 2.0, (5.0, 3.0, 40.0)) if masses else None
    spec = dataclasses.replace(spec, masses=masses, payload=payload, gravity=gravity)
    return dataclasses.replace(model, joint_errors=spec)


def masses_for(n):
    return (PointMass(2, 8.0, (200.0, 0.0, 100.0)), PointMass(3, 2.0, (190.0, 0.0, 20.0)),
            PointMass(min(5, n), 1.0, (0.0, 10.0, 5.0)))


def random_point(model, rng, scale=1e-3):
    """Parameters near nominal; coefficients scaled so every correction is ~`scale` rad."""
    p = model.nominal.copy()
    n_geo = model._n_geometric
    p[:n_geo] += rng.normal(0, 0.01, n_geo)
    q = rng.uniform(-2, 2, (50, model.n_joints))
    W = model._joint_terms.basis(q)
    rms = np.sqrt((W ** 2).mean(axis=0))
    live = rms > 1e-9 * rms.max()  # a mass on a joint's axis gives no torque
    p[n_geo:] = np.where(live, rng.normal(0, scale, rms.size) / np.where(live, rms, 1), 0.0)
    return p


def fd_pose(model, q, p, dp):
    Tp, Tm = model.fk(q, p + dp), model.fk(q, p - dp)
    d = np.empty((q.shape[0], 6))
    d[:, :3] = Tp[:, :3, 3] - Tm[:, :3, 3]
    d[:, 3:] = axis_angle_from_matrix(Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2))
    return d


CASES = [("dh", False, None), ("craig", True, None), ("hayati", False, "masses"),
         ("urdf", False, None), ("dh", True, "masses")]


@pytest.mark.parametrize(("convention", "prismatic", "masses"), CASES)
def test_identification_jacobian_matches_finite_differences(convention, prismatic, masses):
    rng = np.random.default_rng(hash((convention, prismatic, masses)) % 2**32)
    base = random_chain(convention, rng, prismatic)
    model = with_terms(base, masses_for(base.n_joints) if masses else None)
    p = random_point(model, rng)
    q = rng.uniform(-2, 2, (6, model.n_joints))
    if prismatic:
        q[:, 3] = rng.uniform(0, 300, 6)
    J = model.identification_jacobian(q, p, outputs="pose")
    W = np.abs(model._joint_terms.basis(q)).max(axis=0)
    n_geo = model._n_geometric
    for k in range(model.n_params):
        h = 1e-6 if k < n_geo else 1e-6 / max(W[k - n_geo], 1e-12)
        dp = np.zeros(model.n_params)
        dp[k] = h
        Jn = fd_pose(model, q, p, dp) / (2 * h)
        scale = max(np.abs(Jn).max(), 1e-9)
        assert np.abs(J[:, :, k] - Jn).max() / scale < 1e-6, model.parameter_names[k]
    # position-only rows and the restricted columns agree with the full Jacobian
    cols = model.index(list(model.parameter_names[n_geo - 3:n_geo + 5]))
    Jc = model.jacobian_t(q, p, columns=cols)
    np.testing.assert_allclose(Jc.transpose(2, 1, 0), J[:, :3, cols], rtol=0, atol=1e-12)


@pytest.mark.parametrize(("convention", "prismatic", "masses"), CASES)
def test_joint_jacobian_through_corrections(convention, prismatic, masses):
    rng = np.random.default_rng(7)
    base = random_chain(convention, rng, prismatic)
    model = with_terms(base, masses_for(base.n_joints) if masses else None)
    p = random_point(model, rng, scale=3e-2)  # corrections large enough to matter
    q = rng.uniform(-2, 2, (5, model.n_joints))
    if prismatic:
        q[:, 3] = rng.uniform(0, 300, 5)
    Jq = model.joint_jacobian(q, p)
    for i in range(model.n_joints):
        dq = np.zeros(model.n_joints)
        dq[i] = 1e-6
        Tp, Tm = model.fk(q + dq, p), model.fk(q - dq, p)
        d = np.empty((q.shape[0], 6))
        d[:, :3] = Tp[:, :3, 3] - Tm[:, :3, 3]
        d[:, 3:] = axis_angle_from_matrix(Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2))
        np.testing.assert_allclose(Jq[:, :, i], d / 2e-6, rtol=0,
                                   atol=1e-6 * max(np.abs(d).max() / 2e-6, 1.0))
    # d dq / d q itself
    terms, c = model._joint_terms, p[model._n_geometric:]
    D = terms.dq_dq(q, c)
    for i in range(model.n_joints):
        e = np.zeros(model.n_joints)
        e[i] = 1e-6
        Dn = (terms.dq(q + e, c) - terms.dq(q - e, c)) / 2e-6
        np.testing.assert_allclose(D[:, :, i], Dn, rtol=0, atol=1e-8)


def truncated(model, m):
    """The D-H chain up to joint m (1-based), no base, no tool: its fk is link frame m."""
    return SerialModel("sub", model.convention, list(model.joints[:m]))


def test_gravity_forces_are_derivatives_of_the_potential():
    """tau_jm = d(p_m . g)/d q_j for a unit mass at link frame m (independent FK)."""
    ur5 = kinecal.load_model("ur5")
    model = with_terms(ur5, harmonics=0, gravity=(0.0, 0.3, -1.0))
    g = np.array([0.0, 0.3, -1.0]) / np.linalg.norm([0.0, 0.3, -1.0])
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (7, 6))
    W = model._joint_terms.basis(q)
    names = model._joint_terms.names
    plain_tool = dataclasses.replace(ur5, base=None)
    for k, name in enumerate(names):
        if ".compliance." not in name:
            continue
        j = int(name[2:name.index(".")]) - 1
        label = name.rsplit(".", 1)[1]
        e = np.zeros(6)
        e[j] = 1e-6
        if label == "tool":
            plus, minus = plain_tool.positions(q + e), plain_tool.positions(q - e)
        else:
            m = int(label[4:])
            sub = truncated(ur5, m)
            plus, minus = sub.positions((q + e)[:, :m]), sub.positions((q - e)[:, :m])
        dV = (plus - minus) @ g / 2e-6
        lever = model._joint_terms.lever  # forces per lever: coefficients are angles
        np.testing.assert_allclose(W[:, k] * lever, dV, rtol=0, atol=1e-6, err_msg=name)
    # joint 1 of the UR5 is vertical: no torque with gravity along -z
    flat = with_terms(ur5, harmonics=0, gravity=(0, 0, -1))
    cols = [k for k, n in enumerate(flat._joint_terms.names) if n.startswith("dq1.compliance")]
    assert np.abs(flat._joint_terms.basis(q)[:, cols]).max() < 1e-12
    # the lever: the UR5's translations summed (d1, a2, a3, d4, d5, d6 and the tool)
    assert model._joint_terms.lever == pytest.approx(89.159 + 425 + 392.25 + 109.15 + 94.65
                                                     + 82.3 + 0.07 + 31.0)


def test_compliance_sags_along_gravity():
    """A positive compliance moves the tool down (along gravity), never up."""
    ur5 = kinecal.load_model("ur5")
    model = with_terms(ur5, harmonics=0)
    rng = np.random.default_rng(4)
    q = rng.uniform(-np.pi, np.pi, (200, 6))
    g = np.asarray(model.joint_errors.gravity)
    for j in (2, 3, 4):
        p = model.nominal.copy()
        p[model.index([f"dq{j}.compliance.tool"])] = 1e-4
        sag = (model.positions(q, p) - model.positions(q)) @ g
        assert sag.min() > -1e-9 and sag.max() > 1e-3


def test_mass_model_is_the_weighted_generic_basis():
    ur5 = kinecal.load_model("ur5")
    masses = (PointMass(2, 8.4, (0, 0, 0)), PointMass(3, 2.3, (0, 0, 0)),
              PointMass(6, 0.2, (0, 0, 0)))
    generic = with_terms(ur5, harmonics=0)._joint_terms
    spec = dataclasses.replace(joint_errors_for(ur5, ["compliance"]), masses=masses,
                               payload=PointMass(6, 1.5, None), gravity=GRAVITY)
    mass = dataclasses.replace(ur5, joint_errors=spec)._joint_terms
    q = np.random.default_rng(5).uniform(-3, 3, (20, 6))
    Wg, Wm = generic.basis(q), mass.basis(q)
    col = {n: k for k, n in enumerate(generic.names)}
    for j in range(1, 7):
        expect = sum(m.mass * Wg[:, col[f"dq{j}.compliance.link{m.joint}"]]
                     for m in masses if m.joint >= j)
        expect = expect + 1.5 * Wg[:, col[f"dq{j}.compliance.tool"]]
        np.testing.assert_allclose(Wm[:, mass.names.index(f"dq{j}.compliance")], expect,
                                   rtol=1e-12, atol=1e-9)


def test_harmonic_and_scale_corrections():
    ur5 = kinecal.load_model("ur5")
    model = dataclasses.replace(ur5, joint_errors=joint_errors_for(ur5, ["harmonic", "scale"],
                                                                   3))
    p = model.nominal.copy()
    vals = {"dq2.sin1": 1e-4, "dq2.cos3": -2e-4, "dq2.scale": 3e-4, "dq5.cos2": 5e-5}
    p[model.index(list(vals))] = list(vals.values())
    q = np.random.default_rng(6).uniform(-3, 3, (10, 6))
    expect = q.copy()
    expect[:, 1] += 1e-4 * np.sin(q[:, 1]) - 2e-4 * np.cos(3 * q[:, 1]) + 3e-4 * q[:, 1]
    expect[:, 4] += 5e-5 * np.cos(2 * q[:, 4])
    np.testing.assert_allclose(model.positions(q, p), ur5.positions(expect), atol=1e-10)
    assert model.is_angle()[model.index(["dq2.sin1", "dq2.scale"])].tolist() == [True, False]


def test_geometric_models_unchanged_and_zero_coefficients_exact():
    ur5 = kinecal.load_model("ur5")
    q = np.random.default_rng(8).uniform(-3, 3, (30, 6))
    model = with_terms(ur5)
    assert model.parameter_names[:ur5.n_params] == ur5.parameter_names
    assert model.n_params > ur5.n_params and not model.nominal[ur5.n_params:].any()
    # zero coefficients: q + 0 is q, bit for bit
    np.testing.assert_array_equal(model.positions(q), ur5.positions(q))
    np.testing.assert_array_equal(model.fk(q), ur5.fk(q))
    np.testing.assert_array_equal(model.identification_jacobian(q)[:, :, :ur5.n_params],
                                  ur5.identification_jacobian(q))
    # population evaluation = one vector at a time
    rng = np.random.default_rng(9)
    P = np.stack([random_point(model, rng) for _ in range(3)])
    np.testing.assert_array_equal(model.positions(q, P)[2], model.positions(q, P[2]))


def test_with_params_keeps_the_reference_geometry():
    ur5 = kinecal.load_model("ur5")
    model = with_terms(ur5)
    rng = np.random.default_rng(10)
    p = random_point(model, rng)
    cal = model.with_params(p)
    q = rng.uniform(-3, 3, (20, 6))
    np.testing.assert_allclose(cal.fk(q), model.fk(q, p), rtol=0, atol=1e-10)
    np.testing.assert_array_equal(cal.nominal, p)
    assert cal.joint_errors.reference is not None  # the nominal geometry, kept
    # with the calibrated geometry as reference, the forces (hence positions) differ
    moved = dataclasses.replace(cal, joint_errors=dataclasses.replace(cal.joint_errors,
                                                                      reference=None))
    assert np.abs(moved.positions(q) - cal.positions(q)).max() > 0


@pytest.mark.parametrize(("spec", "match"), [
    (dict(harmonics=1, harmonic_joints=(4,)), "prismatic"),
    (dict(compliance=(7,)), "joints 1..6"),
    (dict(scale=(2, 2)), "distinct"),
    (dict(gravity=(0, 0, 0)), "gravity"),
    (dict(harmonics=-1), "order"),
    (dict(values={"dq9.scale": 1.0}), "not a term"),
    (dict(compliance=(1,), reference={"nope": 1.0}), "reference"),
    (dict(compliance=(2,), masses=(PointMass(8, 1.0),)), "masses"),
])
def test_bad_joint_error_specs(spec, match):
    rng = np.random.default_rng(0)
    model = random_chain("dh", rng, prismatic=True)
    with pytest.raises(InputError, match=match):
        dataclasses.replace(model, joint_errors=JointErrors(**spec))
