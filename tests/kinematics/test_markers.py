"""Several markers on one flange: per-pose tool points in FK, Jacobians, files."""

import numpy as np
import pytest

from kinecal import diagnostics
from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.errors import InputError
from kinecal.io.measurements import read_markers, read_measurements, write_measurements
from kinecal.io.models import load_model, save_model
from kinecal.kinematics.serial.markers import model_for_markers
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import axis_angle_from_matrix

POINTS = {"A": [0.0, 0.0, 31.0], "B": [52.0, -3.0, 20.0], "C": [-4.0, 61.0, 25.0]}


def three_marker_ur5():
    return load_model("ur5").with_markers(POINTS)


def test_each_marker_is_its_own_tool_point():
    model = three_marker_ur5()
    assert model.marker_names == ("A", "B", "C")
    assert model.parameter_names[-9:] == tuple(f"tool.{m}.{c}" for m in "ABC" for c in "xyz")
    assert "tool.x" not in model.parameter_names
    assert set(model.parameter_names[-9:]) <= set(model.calibratable)
    rng = np.random.default_rng(0)
    q = random_configurations(model, 50, rng)
    marker = rng.integers(0, 3, 50)
    P = model.positions(q, marker=marker)
    T = model.fk(q, marker=marker)
    np.testing.assert_allclose(T[:, :3, 3], P, atol=1e-12)
    ur5 = load_model("ur5")
    for m, (name, point) in enumerate(POINTS.items()):
        single = SerialModel(name, "dh", ur5.joints, base=ur5.base, tool=point,
                             joint_limits=ur5.joint_limits)
        sel = marker == m
        np.testing.assert_allclose(P[sel], single.positions(q[sel]), rtol=0, atol=1e-12)
    # no marker given: every pose is the first marker; populations broadcast per pose
    np.testing.assert_allclose(model.positions(q), model.positions(q, marker=0 * marker))
    Pp = model.positions(q, np.stack([model.nominal, model.nominal]), marker=marker)
    np.testing.assert_allclose(Pp[1], P, rtol=0, atol=1e-12)


def test_marker_jacobian_columns_are_masked_and_match_finite_differences():
    model = three_marker_ur5()
    rng = np.random.default_rng(1)
    q = random_configurations(model, 12, rng)
    marker = np.tile([0, 1, 2], 4)
    p = model.nominal + rng.normal(0, 0.01, model.n_params)
    J = model.identification_jacobian(q, p, outputs="pose", marker=marker)
    h = 1e-6
    for k in range(model.n_params):
        dp = np.zeros(model.n_params)
        dp[k] = h
        Tp, Tm = model.fk(q, p + dp, marker), model.fk(q, p - dp, marker)
        dpos = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)
        np.testing.assert_allclose(J[:, :3, k], dpos, atol=1e-6, err_msg=model.parameter_names[k])
        drot = axis_angle_from_matrix(Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2)) / (2 * h)
        np.testing.assert_allclose(J[:, 3:, k], drot, atol=1e-7)
    kb = model.index(["tool.B.y"])[0]
    assert np.all(J[marker != 1, :, kb] == 0) and np.all(np.abs(J[marker == 1, :3, kb]).max(1)
                                                           > 0.1)
    s = model.sweep(q, p, marker)
    np.testing.assert_allclose(s.jacobian_t(), model.jacobian_t(q, p, marker=marker))
    np.testing.assert_allclose(model.joint_jacobian(q, p, marker=marker)[:, :, 0],
                               J[:, :, model.index(["theta1"])[0]])


def test_marker_files_round_trip_names_and_numbers(tmp_path):
    model = three_marker_ur5()
    sim = simulate(model, 4, rng=2)
    assert len(sim.data) == 12 and list(sim.data.marker) == [0, 1, 2] * 4
    write_measurements(tmp_path / "m.csv", sim.data, model)
    text = (tmp_path / "m.csv").read_text().splitlines()
    assert text[0].endswith(",marker") and text[1].endswith(",A") and text[2].endswith(",B")
    back = read_measurements(tmp_path / "m.csv", model)
    np.testing.assert_array_equal(back.marker, sim.data.marker)
    # numbers 1..M in the model's order are read as well
    numbered = "\n".join([text[0]] + [",".join(r.split(",")[:-1] + [str("ABC".index(
        r.split(",")[-1]) + 1)]) for r in text[1:]])
    (tmp_path / "n.csv").write_text(numbered + "\n")
    np.testing.assert_array_equal(read_measurements(tmp_path / "n.csv", model).marker,
                                  sim.data.marker)
    # a model without markers takes the file's names (first appearance) and binds them
    plain = load_model("ur5")
    data = read_measurements(tmp_path / "m.csv", plain)
    assert data.marker_names == ("A", "B", "C")
    bound = model_for_markers(plain, data.marker_names)
    assert bound.marker_names == ("A", "B", "C")
    np.testing.assert_allclose(bound.nominal[bound.index(["tool.C.z"])], plain.tool[2])
    # a model file keeps its markers
    save_model(model, tmp_path / "three.yaml")
    assert load_model(tmp_path / "three.yaml").marker_names == ("A", "B", "C")


def test_marker_errors(tmp_path):
    model = three_marker_ur5()
    q = random_configurations(model, 3, np.random.default_rng(0))
    with pytest.raises(InputError, match=r"0\.\.2"):
        model.positions(q, marker=np.array([0, 1, 3]))
    with pytest.raises(InputError, match="no markers"):
        load_model("ur5").positions(q, marker=np.array([0, 0, 0]))
    with pytest.raises(InputError, match="not both"):
        SerialModel("x", "dh", [dict(theta=0, d=1, a=0, alpha=0)], tool=[0, 0, 1],
                    markers=POINTS)
    with pytest.raises(InputError, match="tool frame"):
        SerialModel("x", "dh", [dict(theta=0, d=1, a=0, alpha=0)],
                    tool=[0, 0, 1, 0, 0, 0]).with_markers(["A"])
    with pytest.raises(InputError, match="not the markers"):
        model_for_markers(model, ["A", "D"])
    csv = tmp_path / "bad.csv"
    csv.write_text("q1,q2,q3,q4,q5,q6,x,y,z,marker\n0,0,0,0,0,0,1,2,3,A\n0,0,0,0,0,0,1,2,3,D\n")
    with pytest.raises(InputError, match="row 2") as info:
        read_measurements(csv, model)
    assert "'D'" in str(info.value) and "1..3" in str(info.value)
    csv.write_text("q1,q2,q3,q4,q5,q6,x,y,z\n0,0,0,0,0,0,1,2,3\n")
    with diagnostics.collect() as found:
        assert read_markers(csv, model) == (None, ())
    assert [d.code for d in found] == ["no-marker-column"]
    yaml = tmp_path / "m.yaml"
    yaml.write_text("name: m\nconvention: dh\nangle_unit: deg\njoints:\n"
                    "  - {theta: 0, d: 1, a: 0, alpha: 0}\nmarkers: {1: [0, 0, 1], 2: [1, 2]}\n")
    with pytest.raises(InputError, match="marker 2: expected 3 values"):
        load_model(yaml)
