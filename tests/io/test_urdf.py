"""URDF import and export, checked against pinocchio and yourdfpy (independent FK).

Real URDFs come from the rtb-data wheel (ABB IRB 140, KUKA KR 16, KR 120, KR 210, LBR iiwa
14, PUMA 560); meshes are never loaded.
"""

from importlib import resources

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

from kinecal import calibrate
from kinecal.calibration.serial.problem import resolve_free
from kinecal.calibration.serial.simulate import random_configurations, random_errors
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.io.models import bundled_models, load_model, save_model
from kinecal.io.urdf import load_urdf
from kinecal.io.urdf_export import save_urdf, urdf_joints, urdf_string
from kinecal.kinematics.serial.model import SerialModel

RTB = resources.files("rtbdata") / "xacro"
REAL = {
    "irb140": "abb_irb140_description/urdf/irb140.urdf",
    "kr16": "kuka_description/kuka_kr16/urdf/kr16_2.urdf",
    "kr120": "kuka_description/kuka_kr120/urdf/kr120r2500pro.urdf",
    "kr210": "kuka_description/kuka_kr210/urdf/kr210l150.urdf",
    "iiwa14": "kuka_description/kuka_lbr_iiwa/urdf/lbr_iiwa_14_r820.urdf",
    "puma560": "unimation_puma560_description/urdf/puma560_robot.urdf",
}
TO_MM = {"mm": 1.0, "m": 1000.0}


def pin_positions(urdf_text: str, frame: str, q: np.ndarray) -> np.ndarray:
    """Origin of link `frame` (metres) at each configuration, by pinocchio."""
    model = pin.buildModelFromXML(urdf_text)
    data = model.createData()
    fid = model.getFrameId(frame)
    out = np.empty((len(q), 3))
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, np.asarray(qi, dtype=float))
        out[i] = data.oMf[fid].translation
    return out


def yourdfpy_positions(path, frame: str, q: np.ndarray) -> np.ndarray:
    """Origin of link `frame` in the root link (metres), by yourdfpy's scene graph."""
    robot = yourdfpy.URDF.load(str(path), load_meshes=False)
    out = np.empty((len(q), 3))
    for i, qi in enumerate(q):
        robot.update_cfg(qi)
        out[i] = robot.get_transform(frame, robot.base_link)[:3, 3]
    return out


def check_export(model: SerialModel, params, path, n: int = 1000, seed: int = 0) -> float:
    """Export, load with pinocchio and yourdfpy, compare tool positions (mm); max error."""
    save_urdf(model, path, params)
    text = path.read_text()
    q = random_configurations(model, n, np.random.default_rng(seed))
    mine = model.positions(q, params) * TO_MM[model.length_unit]
    err = 0.0
    for theirs in (pin_positions(text, "tool", q), yourdfpy_positions(path, "tool", q)):
        err = max(err, float(np.abs(theirs * 1000.0 - mine).max()))
    back = load_urdf(path)  # and kinecal reads its own URDF back
    err = max(err, float(np.abs(back.positions(q) * 1000.0 - mine).max()))
    return err


# ---------------------------------------------------------------------------- export
@pytest.mark.parametrize("name", bundled_models())
def test_bundled_model_exports_match_pinocchio_and_yourdfpy(name, tmp_path):
    model = load_model(name)
    assert check_export(model, None, tmp_path / f"{name}.urdf") <= 1e-9


def test_calibrated_ur5_from_demo_data_exports_exactly(tmp_path):
    from kinecal.io.measurements import read_measurements

    model = load_model("ur5")
    res = calibrate(model, read_measurements("ur5-laser-tracker:grid", model))
    assert res.val_before is None and res.errors_after.mean() < 0.2  # mm: a real fit
    assert np.abs(res.params - model.nominal).max() > 1e-3  # the geometry did change
    assert check_export(model, res.params, tmp_path / "ur5-cal.urdf") <= 1e-9


def test_parallel_axis_dh_export_stays_within_the_arm():
    """A calibrated D-H table with nearly parallel axes 2 and 3 puts the common normal
    574 m along the axis (d2, d3); the exported joint origins stay within the arm."""
    ur5 = load_model("ur5")
    joints = [dict(j) for j in ur5.joints]
    D, eps = 574_000.0, 1e-4  # mm, rad
    joints[1].update(d=D, alpha=eps)
    joints[2].update(d=-D)
    model = SerialModel("ur5-parallel", "dh", joints, base=ur5.base, tool=ur5.tool,
                        joint_limits=ur5.joint_limits)
    q = random_configurations(model, 1000, np.random.default_rng(4))
    reach = np.linalg.norm(model.positions(q), axis=1).max()
    assert reach < 1500.0  # the arm itself is UR5-sized
    origins = [np.linalg.norm(j.origin[:3, 3]) for j in urdf_joints(model)]
    assert max(origins) < 1000.0, origins
    assert max(abs(j.get("d", 0)) for j in model.joints) > 500_000  # what naive export writes
    text = urdf_string(model)
    mine = model.positions(q)
    # D-H composes a 574 m detour, pinocchio the compact tree: both agree to round-off
    assert np.abs(pin_positions(text, "tool", q) * 1000.0 - mine).max() <= 1e-9 * D


def test_urdf_model_export_keeps_link_frames_and_folds_offsets(tmp_path):
    model = load_urdf(RTB / REAL["kr16"])
    p = model.nominal
    p[model.index(["joint_a2.offset", "joint_a3.x", "base.z"])] = [0.1, 0.7, 0.25]
    text = urdf_string(model, p)
    joints = {j.name: j for j in urdf_joints(model, p)}
    assert joints["joint_a1"].parent == "base_link" and joints["joint_a1"].child == "link_1"
    assert joints["base_joint"].parent == "world"  # a base frame that moved: the world link
    np.testing.assert_allclose(joints["joint_a3"].origin[:3, 3], [0.7, 0, 0], atol=1e-15)
    q = random_configurations(model, 200, np.random.default_rng(2))
    np.testing.assert_allclose(pin_positions(text, "tool", q), model.positions(q, p),
                               rtol=0, atol=1e-12)


def test_export_escapes_names_and_writes_metres(tmp_path):
    model = SerialModel("a<b>&\"c\"", "dh", [dict(theta=0, d=100, a=0, alpha=0)])
    text = urdf_string(model, comment="from x -- y")
    assert "&lt;" in text and "&amp;" in text and "&quot;" in text
    assert 'xyz="0.0 0.0 0.1"' in text  # 100 mm
    assert pin.buildModelFromXML(text).nq == 1


# ---------------------------------------------------------------------------- import
@pytest.mark.parametrize("robot", list(REAL))
def test_real_urdf_import_fk_identifiability_and_recovery(robot):
    path = RTB / REAL[robot]
    model = load_urdf(path)
    assert model.convention == "urdf" and model.length_unit == "m"
    tip = model.joints[-1].get("child")
    rng = np.random.default_rng(7)
    q = random_configurations(model, 1000, rng)
    theirs = pin_positions(path.read_text(), tip, q)
    assert np.abs(model.positions(q) - theirs).max() * 1000.0 <= 1e-9
    # identifiability: position measurements, free base and tool point -> 4 R + 3 at
    # most (Everett, Driels and Mooring 1987); the analysis finds it at a perturbed geometry
    true = model.nominal + random_errors(model, rng)
    hidden = urdf_string(model, true)  # the "real" arm, known only through pinocchio
    q_cal = random_configurations(model, 60, rng)
    q_val = random_configurations(model, 200, rng)
    data = Measurements(q_cal, pin_positions(hidden, "tool", q_cal))
    val = Measurements(q_val, pin_positions(hidden, "tool", q_val))
    _, report = resolve_free(model, data, "all", params=true)
    assert report.rank == 4 * model.n_joints + 3
    res = calibrate(model, data, validate=val)
    assert res.val_before.mean() > 1e-3  # millimetres off before
    assert res.val_after.max() * 1000.0 <= 1e-9, res.val_after.max()


def test_default_chain_skips_fixed_side_frames():
    model = load_urdf(RTB / REAL["irb140"])  # base_link also has a fixed child "base"
    assert [j.get("name", j.get("frame")) for j in model.joints][-1] == "joint_6-tool0"
    assert model.n_joints == 6
    assert "joint_6-tool0.pitch" in model.fixed_names  # fixed joints stay fixed
    assert "joint_2.x" in model.calibratable and "base.x" in model.calibratable
    short = load_urdf(RTB / REAL["irb140"], base_link="link_2", tip_link="link_5")
    assert short.n_joints == 3
    assert [j["name"] for j in short.joints] == ["joint_3", "joint_4", "joint_5"]


SYNTH = """<?xml version="1.0"?>
<robot name="synth">
  <link name="world"/><link name="slide"/><link name="turn"/><link name="mount"/>
  <link name="wrist"/><link name="cam"/><link name="tcp"/>
  <joint name="lift" type="prismatic">
    <origin xyz="0.1 -0.2 0.3" rpy="0.1 0.2 0.3"/><parent link="world"/><child link="slide"/>
    <axis xyz="0 0.6 0.8"/><limit lower="-0.2" upper="0.5" effort="10" velocity="0.5"/>
  </joint>
  <joint name="spin" type="continuous">
    <origin xyz="0 0 0.4" rpy="0 0 0"/><parent link="slide"/><child link="turn"/>
    <axis xyz="0.3 -0.5 0.81"/>
  </joint>
  <joint name="bracket" type="fixed">
    <origin xyz="0.05 0 0.1" rpy="0 1.57079632679 0"/><parent link="turn"/><child link="mount"/>
  </joint>
  <joint name="tilt" type="revolute">
    <origin xyz="0.2 0.01 0" rpy="-0.4 0 1.2"/><parent link="mount"/><child link="wrist"/>
    <axis xyz="0 -1 0"/><limit lower="-1.5" upper="1.5" effort="5" velocity="1"/>
  </joint>
  <joint name="camera" type="fixed">
    <origin xyz="0 0.03 0.02"/><parent link="wrist"/><child link="cam"/>
  </joint>
  <joint name="tool" type="fixed">
    <origin xyz="0 0 0.15"/><parent link="wrist"/><child link="tcp"/>
  </joint>
  EXTRA
</robot>
"""


def _synth(tmp_path, extra="", name="synth.urdf"):
    path = tmp_path / name
    path.write_text(SYNTH.replace("EXTRA", extra))
    return path


def test_prismatic_continuous_general_axes_against_yourdfpy_and_pinocchio(tmp_path):
    path = _synth(tmp_path)
    model = load_urdf(path, tip_link="tcp")
    assert model.joint_kinds == ("prismatic", "revolute", "revolute")
    assert model.joints[1]["type"] == "continuous"
    np.testing.assert_allclose(model.joint_limits[0], [-0.2, 0.5])
    assert [j.get("frame") for j in model.joints if "frame" in j] == ["bracket", "tool_frame"]
    q = random_configurations(model, 300, np.random.default_rng(3))
    np.testing.assert_allclose(model.positions(q), yourdfpy_positions(path, "tcp", q),
                               rtol=0, atol=1e-12)
    pm = pin.buildModelFromUrdf(str(path))
    assert pm.nq == 4  # the continuous joint is (cos, sin) in pinocchio
    qp = np.column_stack([q[:, 0], np.cos(q[:, 1]), np.sin(q[:, 1]), q[:, 2]])
    np.testing.assert_allclose(model.positions(q), pin_positions(path.read_text(), "tcp", qp),
                               rtol=0, atol=1e-12)
    # model file round trip keeps kinds, limits, effort and velocity
    save_model(model, tmp_path / "synth.yaml")
    back = load_model(tmp_path / "synth.yaml")
    np.testing.assert_allclose(back.positions(q), model.positions(q), rtol=0, atol=1e-12)
    assert back.joints[0]["effort"] == 10.0
    # and exporting it again writes the same kinematics, continuous joint included
    text = urdf_string(back)
    assert 'type="continuous"' in text and 'effort="10.0"' in text
    np.testing.assert_allclose(pin_positions(text, "tool", qp), model.positions(q),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("extra", "kwargs", "match"),
    [
        ("", {}, "branches .*--tip-link .*tcp, cam"),
        ('<link name="f"/><joint name="finger" type="prismatic"><parent link="wrist"/>'
         '<child link="f"/><limit lower="0" upper="1" effort="1" velocity="1"/>'
         '<mimic joint="tilt"/></joint>', {"tip_link": "f"}, "mimics joint tilt"),
        ('<link name="f"/><joint name="free" type="floating"><parent link="wrist"/>'
         '<child link="f"/></joint>', {"tip_link": "f"}, "floating"),
        ('<link name="f"/><joint name="flat" type="planar"><parent link="wrist"/>'
         '<child link="f"/></joint>', {"tip_link": "f"}, "planar"),
        ("", {"tip_link": "nowhere"}, "no link 'nowhere'"),
        ("", {"base_link": "wrist", "tip_link": "slide"}, "not below"),
        ("", {"base_link": "wrist", "tip_link": "cam"}, "no moving joint"),
        ("", {"base_link": "x", "tip_link": "tcp"}, "no link 'x'"),
        ('<link name="r2"/><link name="r3"/><joint name="k" type="fixed"><parent link="r2"/>'
         '<child link="r3"/></joint>', {}, "2 root links"),
    ],
)
def test_urdf_chain_errors(tmp_path, extra, kwargs, match):
    with pytest.raises(InputError, match=match):
        load_urdf(_synth(tmp_path, extra), **kwargs)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("<robot name='x'><link name='a'/>", "not well-formed XML"),
        ("<model/>", "expected <robot>"),
        ("<robot name='x'><link name='a'/><link name='b'/><joint name='j' type='prismatic'>"
         "<parent link='a'/><child link='b'/></joint></robot>",
         "prismatic joint j: missing <limit"),
        ("<robot name='x'><link name='a'/><link name='b'/><joint name='j' type='prismatic'>"
         "<parent link='a'/><child link='b'/><limit effort='1' velocity='1'/></joint></robot>",
         "prismatic joint j: expected"),
        ("<robot name='x'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
         "<parent link='a'/></joint></robot>", "missing <child"),
    ],
)
def test_bad_urdf_files(tmp_path, text, match):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(InputError, match=match) as info:
        load_urdf(path)
    assert "bad.urdf" in str(info.value)


def test_xacro_and_missing_files_and_options_on_yaml_models(tmp_path):
    with pytest.raises(InputError, match="expand it first"):
        load_model(tmp_path / "robot.urdf.xacro")
    with pytest.raises(InputError, match="file not found"):
        load_model(tmp_path / "nothing.urdf")
    with pytest.raises(InputError, match="URDF models only"):
        load_model("ur5", tip_link="tool0")


def test_revolute_without_limits_warns(tmp_path):
    from kinecal import diagnostics

    path = tmp_path / "nolimit.urdf"
    path.write_text("<robot name='x'><link name='a'/><link name='b'/><joint name='j' "
                    "type='revolute'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/>"
                    "<limit effort='1' velocity='1'/></joint></robot>")
    with diagnostics.collect() as found:
        model = load_urdf(path)
    assert [d.code for d in found] == ["urdf-joint-limits"]
    np.testing.assert_allclose(model.joint_limits, [[-np.pi, np.pi]])


@pytest.mark.parametrize("kwargs", [{}, {"base_link": "link_1", "tip_link": "link_6"}])
def test_calibrated_values_written_into_the_source_urdf(tmp_path, kwargs):
    from kinecal.io.urdf_patch import patched_urdf, save_patched_urdf

    source = RTB / REAL["irb140"]
    model = load_urdf(source, **kwargs)
    p = model.nominal + random_errors(model, np.random.default_rng(5))
    text = patched_urdf(source, model, p, comment="calibrated -- test")
    original = source.read_text()
    assert text.count("<visual>") == original.count("<visual>") == 7  # meshes kept
    assert 'name="base_link-base"' in text  # the side frame too
    q = random_configurations(model, 300, np.random.default_rng(6))
    pm = pin.buildModelFromXML(text)
    pd = pm.createData()
    tool = pm.getFrameId("tool")
    frame = pm.getFrameId("measurement_frame") if kwargs else None
    theirs = []
    for qi in q:
        full = np.zeros(pm.nq)
        if kwargs:
            full[1:6] = qi
        else:
            full[:] = qi
        pin.framesForwardKinematics(pm, pd, full)
        T = pd.oMf[tool].homogeneous
        if kwargs:  # the chain starts below the file's root: measured from that frame
            T = np.linalg.inv(pd.oMf[frame].homogeneous) @ T
        theirs.append(T[:3, 3])
    assert np.abs(np.array(theirs) - model.positions(q, p)).max() * 1000.0 <= 1e-9
    save_patched_urdf(source, model, tmp_path / "cal.urdf", p)
    assert yourdfpy.URDF.load(str(tmp_path / "cal.urdf"), load_meshes=False).validate()
    with pytest.raises(InputError, match="not the URDF the model came from"):
        patched_urdf(RTB / REAL["kr16"], model, p)
    with pytest.raises(InputError, match="only a model loaded from this URDF"):
        patched_urdf(source, load_model("ur5"))
