"""System files (``kind: system``), a system's measurement files (joint columns by name,
``tip`` and ``carrier`` columns, blanks off a row's chain) and the whole tree as URDF, read
back by pinocchio."""

import re

import numpy as np
import pinocchio as pin
import pytest

from kinecal.data import GaugeMeasurements, Measurements
from kinecal.errors import InputError
from kinecal.io.system_data import read_system_data, write_system_data
from kinecal.io.systems import is_system_spec, load_machine, load_system
from kinecal.io.urdf_tree_export import tree_urdf_string
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.tree import SystemModel

RAIL = """kind: system
name: cell
length_unit: mm
angle_unit: deg
parts:
  - name: rail
    model:
      convention: dh
      length_unit: mm
      angle_unit: deg
      joints: [{theta: 0, d: 0, a: 0, alpha: 0, type: prismatic}]
      joint_limits: [[0, 1500]]
    base: [0, 0, 0, 0, 90, 0]
  - name: arm
    model: ur5
    on: rail
    base: [-250, 0, 0, 0, -90, 0]
{extra}"""


def write(tmp_path, text, name="cell.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_system_file_composes_parts(tmp_path):
    system = load_machine(write(tmp_path, RAIL.replace("{extra}", "")))
    assert isinstance(system, SystemModel) and system.tips == ("rail", "arm")
    assert system.joint_names[:2] == ("rail.q1", "arm.q1")
    assert {"arm.base.x", "arm.theta2", "arm.tool.z", "rail.d1"} <= set(system.calibratable)
    rail = set(system.chain_parameters("rail")) - {"rail.tool.x", "rail.tool.y", "rail.tool.z"}
    assert rail < set(system.chain_parameters("arm"))  # all but the rail's own tool
    assert "rail.d1" in system.shared_parameters()  # the arm rides on the rail
    # the arm's chain equals the rail's flange times the mount times the bundled ur5
    ur5 = load_machine("ur5")
    q = np.zeros((1, system.n_joints))
    q[0, 0] = 700.0
    q[0, 1:7] = [0.1, -1.2, 1.0, -0.5, 0.3, 0.7]
    mount = system.link_poses(q, "arm.base")[0]
    np.testing.assert_allclose(mount[:3, 3], [700.0, 0.0, 250.0], atol=1e-12)  # along x
    np.testing.assert_allclose(system.fk(q, marker=np.array([1]))[0],
                               mount @ ur5.fk(q[:, 1:7])[0], atol=1e-10)


@pytest.mark.parametrize(("extra", "match"), [
    ("  - name: arm\n    model: ur5\n", "given twice"),
    ("  - name: pos\n    model: ur5\n    on: table\n", "not a part"),
    ("  - name: big\n    model: {convention: dh, length_unit: m, angle_unit: rad, joints: "
     "[{theta: 0, d: 1, a: 0, alpha: 0}]}\n", "length unit"),
    ("  - name: a.b\n    model: ur5\n", "part name"),
    ("  - name: c\n    model: ur5\n    on: d\n  - name: d\n    model: ur5\n    on: c\n",
     "not below"),
])
def test_bad_system_files_are_refused(tmp_path, extra, match):
    with pytest.raises(InputError, match=match):
        load_machine(write(tmp_path, RAIL.replace("{extra}", extra)))


def test_a_system_is_not_a_serial_model_for_load_model(tmp_path):
    from kinecal.io.models import load_model

    path = write(tmp_path, RAIL.replace("{extra}", ""))
    with pytest.raises(InputError, match="system file"):
        load_model(path)
    assert is_system_spec(path) and is_system_spec("rail-cell")
    assert isinstance(load_machine("ur5"), SerialModel)


def _cell(tmp_path):
    system = load_system(write(tmp_path, RAIL.replace("{extra}", (
        "  - name: table\n    model: {convention: dh, length_unit: mm, angle_unit: deg, "
        "joints: [{theta: 0, d: 300, a: 0, alpha: -90}, {theta: 0, d: 100, a: 0, alpha: 0}]"
        ", joint_limits: [[-90, 90], [-180, 180]]}\n    base: [800, 700, 0, 0, 0, 0]\n"))))
    rng = np.random.default_rng(0)
    lo, hi = system.joint_limits[:, 0], system.joint_limits[:, 1]
    q = rng.uniform(np.maximum(lo, -3), np.minimum(hi, 3), (6, system.n_joints))
    return system, q


def test_system_files_round_trip(tmp_path):
    system, q = _cell(tmp_path)
    tips = np.array([0, 1, 1, 2, 2, 1])
    from kinecal.calibration.blocks.system_simulate import _fill

    q = _fill(system, q, tips, system.link_joints("table"))
    xyz = system.positions(q, marker=tips)
    data = Measurements(q, xyz, marker=tips, marker_names=system.tips)
    write_system_data(tmp_path / "t.csv", data, system)
    back = read_system_data(tmp_path / "t.csv", system)
    np.testing.assert_array_equal(back.marker, tips)
    np.testing.assert_allclose(system.positions(back.q, marker=back.marker), xyz, atol=1e-12)
    header, first = (tmp_path / "t.csv").read_text().splitlines()[:2]
    assert header.startswith("rail.q1,arm.q1") and header.endswith(",tip,x,y,z")
    assert first.split(",")[2:7] == [""] * 5 or "rail" not in first  # blanks off the chain
    touches = GaugeMeasurements("point", q, np.array([0, 0, 1, 1, 0, 0]), ("A", "B"),
                                marker=tips, marker_names=system.tips,
                                carrier=np.array([-1, 0, -1, -1, -1, 0]),
                                carrier_names=("table",))
    write_system_data(tmp_path / "p.csv", touches, system)
    back = read_system_data(tmp_path / "p.csv", system)
    np.testing.assert_array_equal(back.carrier, touches.carrier)
    assert back.carrier_names == ("table",)


def _edit(tmp_path, row, column, value, name="t.csv"):
    """The file ``t.csv`` with one cell replaced (data row `row`, 1-based)."""
    lines = (tmp_path / name).read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[row].split(",")
    cells[header.index(column)] = value
    lines[row] = ",".join(cells)
    out = tmp_path / "bad.csv"
    out.write_text("\n".join(lines) + "\n")
    return out


def test_bad_rows_are_refused_with_their_row(tmp_path):
    system, q = _cell(tmp_path)
    tips = np.array([0, 1, 2, 1, 0, 2])
    from kinecal.calibration.blocks.system_simulate import _fill

    q = _fill(system, q, tips)
    data = Measurements(q, system.positions(q, marker=tips), marker=tips,
                        marker_names=system.tips)
    write_system_data(tmp_path / "t.csv", data, system)
    cases = [  # (row, column, value, expected words)
        (1, "arm.q2", "0.5", "arm.q2 is not on the row's chain (tip rail)"),
        (2, "arm.q3", "", "arm.q3 is blank"),
        (2, "rail.q1", "", "rail.q1 is blank"),  # the arm rides on the rail
        (3, "tip", "nope", "expected one of the system's tips"),
        (4, "arm.q1", "abc", "expected a finite number"),
    ]
    for row, column, value, words in cases:
        with pytest.raises(InputError, match=re.escape(words)) as err:
            read_system_data(_edit(tmp_path, row, column, value), system)
        assert err.value.row == row
    plain = tmp_path / "plain.csv"
    plain.write_text("q1,q2,x,y,z\n1,2,3,4,5\n")
    with pytest.raises(InputError, match="joint names"):
        read_system_data(plain, system)
    notip = tmp_path / "notip.csv"
    notip.write_text("rail.q1,x,y,z\n100,1,2,3\n")
    with pytest.raises(InputError, match="no tip column"):
        read_system_data(notip, system)
    assert read_system_data(notip, system, tip="rail").marker.tolist() == [0]


def test_the_tree_as_urdf_is_the_system_in_pinocchio(tmp_path):
    system, q = _cell(tmp_path)
    rng = np.random.default_rng(5)
    p = system.nominal + rng.normal(0.0, 1e-3, system.n_params)  # a calibrated system
    path = tmp_path / "tree.urdf"
    path.write_text(tree_urdf_string(system, p))
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    worst = 0.0
    for i in range(len(q)):
        qp = np.array([q[i, k] / (1000.0 if system.joint_kinds[k] == "prismatic" else 1.0)
                       for k in range(system.n_joints)])
        order = [model.joints[model.getJointId(n)].idx_q for n in system.joint_names]
        cfg = pin.neutral(model)
        cfg[order] = qp
        pin.framesForwardKinematics(model, data, cfg)
        for t, tip in enumerate(system.tips):
            T = data.oMf[model.getFrameId(f"{tip}_tool")].homogeneous
            mine = system.fk(q[i:i + 1], p, np.array([t]))[0]
            worst = max(worst, float(np.abs(T[:3, 3] * 1000.0 - mine[:3, 3]).max()))
            worst = max(worst, 1000.0 * float(np.abs(T[:3, :3] - mine[:3, :3]).max()))
    assert worst < 1e-9  # mm
