"""Hostile inputs to the model readers, export and compensate, as an outside tester tries
them: corrupt URDF numbers and names, absurd lengths, the wrong kind of result JSON, a URDF
saved as .xml, a model file written under a .urdf name. Every case: exit 2, one line naming
the file and what was expected, nothing written; or the right answer."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest
import yaml

from kinecal.cli import main
from kinecal.io.models import load_model

KR16 = resources.files("rtbdata") / "xacro" / "kuka_description/kuka_kr16/urdf/kr16_2.urdf"
LIMIT = '<limit lower="-3" upper="3" effort="1" velocity="1"/>'


def _joint(name, parent, child, xyz="0 0 0.1", rpy="0 0 0", axis="0 0 1", kind="revolute"):
    limit = LIMIT if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/>'
            f'<axis xyz="{axis}"/>{limit}</joint>')


def _urdf(body: str) -> str:
    return f'<?xml version="1.0"?>\n<robot name="r">\n{body}\n</robot>\n'


def _chain(**first) -> str:
    links = "".join(f'<link name="l{i}"/>' for i in range(4))
    joints = _joint("j1", "l0", "l1", **first) + _joint("j2", "l1", "l2") + \
        _joint("j3", "l2", "l3")
    return links + joints


def _fail(args, capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("kinecal: error:") and err.count("\n") == 1, err
    return err


@pytest.fixture
def joints3(tmp_path):
    path = tmp_path / "j.csv"
    path.write_text("q1,q2,q3\n10,20,30\n")
    return path


@pytest.mark.parametrize(("body", "needle"), [
    # yourdfpy turned an infinite x into NaNs of other components: "yaw: got nan"
    (_chain(xyz="inf 0 0.1"), 'joint j1: <origin xyz="inf 0 0.1">: expected three finite'),
    (_chain(rpy="0 nan 0"), 'joint j1: <origin rpy="0 nan 0">: expected three finite'),
    (_chain(xyz="0 0"), 'joint j1: <origin xyz="0 0">'),  # was a numpy broadcast error
    (_chain(axis="1 abc 0"), 'joint j1: <axis xyz="1 abc 0">'),
    # was accepted: two links of one name (urdfdom refuses them)
    (_chain() + '<link name="l2"/>', "two <link> elements named 'l2'"),
    # a duplicate joint name off the chain was accepted
    (_chain() + '<link name="s"/>' + _joint("j2", "l3", "s", kind="fixed"),
     "two <joint> elements named 'j2'"),
    # was accepted: a joint's child that is not a link of the file (urdfdom refuses it)
    (_chain() + _joint("j4", "l3", "ghost"), "joint j4: child link 'ghost' is not a <link>"),
    # was "0 root links (a cycle)"
    ('<link name="only"/>', "no <joint> elements"),
])
def test_corrupt_urdf_is_named(body, needle, tmp_path, joints3, capsys):
    path = tmp_path / "bad.urdf"
    path.write_text(_urdf(body))
    err = _fail(["fk", str(path), str(joints3)], capsys)
    assert "bad.urdf" in err and needle in err


@pytest.mark.parametrize("command", [["fk", "J"], ["identifiability", "--poses", "20"],
                                     ["simulate", "--poses", "20", "--out", "OUT"]])
def test_absurd_length_refused_before_the_jacobian_overflows(command, tmp_path, joints3,
                                                           capsys):
    """1e300 m in an origin: fk printed 2.9e300, identifiability said 'scale: expected 30
    positive factors', calibrate 'Jacobian contains NaN or infinite values'."""
    path = tmp_path / "big.urdf"
    path.write_text(_urdf(_chain(xyz="1e300 0 0.1")))
    args = [a.replace("J", str(joints3)).replace("OUT", str(tmp_path / "o.csv"))
            for a in command]
    err = _fail([args[0], str(path), *args[1:]], capsys)
    assert "big.urdf" in err and "j1.x = 1e+300" in err and "at most 1e+09" in err
    assert not (tmp_path / "o.csv").exists()


def test_absurd_length_in_a_model_file(tmp_path, capsys):
    data = yaml.safe_load((resources.files("kinecal") / "robots" / "ur5.yaml").read_text())
    data["joints"][1]["a"] = 1e300
    path = tmp_path / "big.yaml"
    path.write_text(yaml.safe_dump(data))
    err = _fail(["identifiability", str(path), "--poses", "20"], capsys)
    assert "big.yaml" in err and "a2 = 1e+300" in err
    # the largest machines stay far inside the bound
    data["joints"][1]["a"] = 1e6  # 1 km in mm
    path.write_text(yaml.safe_dump(data))
    assert load_model(path).nominal[load_model(path).index(["a2"])[0]] == 1e6


def test_urdf_saved_as_xml_is_read_as_urdf(tmp_path, capsys):
    """A URDF named robot.xml was parsed as YAML: 'expected a YAML mapping'."""
    xml = tmp_path / "kr16.xml"
    xml.write_text(KR16.read_text())
    q = np.radians([[10, -80, 60, 20, 50, 60], [0, -30, 20, 0, 40, 0]])
    ours = load_model(xml).positions(q)
    np.testing.assert_array_equal(ours, load_model(str(KR16)).positions(q))
    joints = tmp_path / "j.csv"
    joints.write_text("q1,q2,q3,q4,q5,q6\n10,-80,60,20,50,60\n")
    assert main(["fk", str(xml), str(joints)]) == 0
    got = np.array(capsys.readouterr().out.splitlines()[1].split(","), dtype=float)
    np.testing.assert_allclose(got, ours[0], rtol=1e-9)
    # every command that takes --tip-link, and the export into a copy of the file, treat it
    # as the URDF it is (they judged by the suffix: 'applies to URDF models only')
    assert main(["fk", str(xml), str(joints), "--tip-link", "tool0"]) == 0
    exact = load_model(xml, tip_link="tool0").fk(q[:1])[0, :3, 3]  # what fk prints, bit for bit
    assert capsys.readouterr().out.splitlines()[1] == ",".join(map(repr, exact.tolist()))
    meas = tmp_path / "m.csv"
    assert main(["simulate", str(xml), "--poses", "30", "--seed", "1", "--out", str(meas),
                 "--quiet"]) == 0
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text(f"jobs:\n  - {{name: a, model: {xml}, data: {meas}, tip_link: tool0}}\n")
    assert main(["batch", str(jobs), "--out", str(tmp_path / "runs"), "--quiet"]) == 0
    res = tmp_path / "r.json"
    assert main(["calibrate", str(xml), str(meas), "--out", str(res), "--quiet"]) == 0
    assert main(["compensate", str(res), str(joints), "--nominal", str(xml), "--tip-link",
                 "tool0", "--out", str(tmp_path / "c.csv"), "--quiet"]) == 0
    assert main(["export", str(res), "--nominal", str(xml), "--out",
                 str(tmp_path / "cal.urdf")]) == 0
    assert (tmp_path / "cal.urdf").read_text().count("<mesh") == KR16.read_text().count("<mesh")
    capsys.readouterr()


@pytest.fixture(scope="module")
def other_results(tmp_path_factory):
    d = tmp_path_factory.mktemp("results")
    assert main(["handeye", "handeye-camodocal", "--out", str(d / "he.json"), "--quiet"]) == 0
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "30", "--seed", "1",
                 "--out", str(d / "st.csv")]) == 0
    assert main(["stewart", "calibrate", "liu2008-cmm", str(d / "st.csv"), "--out",
                 str(d / "st.json"), "--quiet"]) == 0
    (d / "prog.csv").write_text("q1,q2,q3,q4,q5,q6\n10,-80,60,20,50,60\n")
    return d


@pytest.mark.parametrize(("name", "kind"), [("he.json", "a hand-eye calibration result"),
                                            ("st.json", "a Stewart-platform calibration")])
@pytest.mark.parametrize("command", ["export", "compensate", "compensate-nominal", "fk"])
def test_results_of_other_calibrations_are_named(name, kind, command, other_results, capsys):
    """Before: 'give --nominal MODEL', 'the result is for model liu2008-cmm, not a bundled
    one' (it is a bundled geometry), 'expected ... a parameters mapping'."""
    result, prog, out = (str(other_results / n) for n in (name, "prog.csv", "o.out"))
    args = {"export": ["export", result, "--out", out + ".urdf"],
            "compensate": ["compensate", result, prog, "--out", out],
            "compensate-nominal": ["compensate", result, prog, "--nominal", "ur5", "--out",
                                   out],
            "fk": ["fk", "ur5", prog, "--params", result]}[command]
    err = _fail(args, capsys)
    assert name in err and kind in err and "kinecal calibrate --out" in err
    assert not list(other_results.glob("o.out*"))


def test_export_yaml_under_a_urdf_name_is_refused(tmp_path, capsys):
    """It was written, and every later command read it as broken XML."""
    out = tmp_path / "ur5.urdf"
    err = _fail(["export", "ur5", "--format", "yaml", "--out", str(out)], capsys)
    assert "--format" in err and "ur5.urdf" in err
    assert not out.exists()
    assert main(["export", "ur5", "--format", "urdf", "--out", str(out)]) == 0
    assert out.read_text().lstrip().startswith("<")


def test_bundled_name_as_calibrated_model(tmp_path, capsys):
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3,q4,q5,q6\n10,-80,60,20,50,60\n")
    err = _fail(["compensate", "ur5", str(prog), "--out", str(tmp_path / "o.csv")], capsys)
    assert "bundled nominal model" in err and "--nominal" in err


def test_result_json_round_trip_still_works(other_results, tmp_path, capsys):
    """The kind checks leave serial results alone."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "ur5", "--poses", "40", "--seed", "2", "--out", str(meas),
                 "--quiet"]) == 0
    res = tmp_path / "r.json"
    assert main(["calibrate", "ur5", str(meas), "--out", str(res), "--quiet"]) == 0
    assert json.loads(res.read_text())["model"] == "ur5"
    assert main(["export", str(res), "--out", str(tmp_path / "c.urdf")]) == 0
    capsys.readouterr()


def test_urdf_directory_device_and_size_cap(tmp_path, joints3, capsys, monkeypatch):
    folder = tmp_path / "robot.urdf"
    folder.mkdir()
    assert "is a directory, expected a URDF file" in _fail(["fk", str(folder), str(joints3)],
                                                           capsys)
    device = tmp_path / "zero.urdf"
    device.symlink_to("/dev/zero")
    assert "is a device" in _fail(["fk", str(device), str(joints3)], capsys)
    # the whole file is read once (bounded) and parsed in one feed
    import kinecal.io.urdf as urdf_module

    path = tmp_path / "padded.urdf"
    path.write_text(_urdf(_chain() + "<!-- " + "x" * 5000 + " -->"))
    monkeypatch.setattr(urdf_module, "MAX_TEXT_BYTES", 4000)
    err = _fail(["fk", str(path), str(joints3)], capsys)
    assert "padded.urdf" in err and "too large for a URDF" in err


def _gripper(tmp_path):
    """An arm whose flange carries two prismatic fingers (the second mimics the first)."""
    body = _chain() + '<link name="f1"/><link name="f2"/>' + \
        _joint("fa", "l3", "f1", kind="prismatic") + \
        _joint("fb", "l3", "f2", kind="prismatic").replace("</joint>",
                                                           '<mimic joint="fa"/></joint>')
    path = tmp_path / "gripper.urdf"
    path.write_text(_urdf(body))
    return path


def test_noise_free_fit_reports_no_outliers(tmp_path, capsys):
    """Round-off residuals (1.8e-15 m against a 3.6e-16 m median) were flagged as an
    outlier pose on a clean, noise-free calibration."""
    urdf = _gripper(tmp_path)
    err = _fail(["fk", str(urdf), str(tmp_path / "none.csv")], capsys)
    assert "branches (fa, fb)" in err and "f1, f2" in err
    meas = tmp_path / "g.csv"
    assert main(["simulate", str(urdf), "--tip-link", "f1", "--poses", "30", "--seed", "2",
                 "--out", str(meas), "--quiet"]) == 0
    out = tmp_path / "r.json"
    assert main(["calibrate", str(urdf), str(meas), "--tip-link", "f1", "--out", str(out),
                 "--quiet"]) == 0
    assert "outliers" not in capsys.readouterr().err
    result = json.loads(out.read_text())
    assert result["calibration"]["after"]["max"] < 1e-12
    assert not [w for w in result["warnings"] if w["code"] == "outliers"]
    # the mimic finger's chain is a robot system (docs/systems.md): its joints by name
    assert "a system's joint columns are its joint names" in _fail(
        ["fk", str(urdf), str(meas), "--tip-link", "f2"], capsys)


def test_calibrate_model_out_under_a_urdf_name_is_refused_before_work(tmp_path, capsys):
    """--model-out calibrated.urdf wrote YAML that fk, compensate and export then failed to
    read ('not well-formed XML')."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "ur5", "--poses", "40", "--seed", "2", "--out", str(meas),
                 "--quiet"]) == 0
    out, res = tmp_path / "cal.urdf", tmp_path / "r.json"
    err = _fail(["calibrate", "ur5", str(meas), "--model-out", str(out), "--out", str(res)],
                capsys)
    assert "--model-out" in err and "cal.urdf" in err and "kinecal export" in err
    assert not out.exists() and not res.exists()
    from kinecal.errors import InputError
    from kinecal.io.models import save_model

    with pytest.raises(InputError, match="named like a URDF"):
        save_model(load_model("ur5"), tmp_path / "x.URDF")


def test_csv_from_a_pipe_is_named(tmp_path, capsys):
    """A CSV read from a pipe was reported as 'empty file' (its header had been consumed
    by a first reading)."""
    import os
    import threading

    fifo = tmp_path / "joints.csv"
    os.mkfifo(fifo)

    def feed():
        try:
            with open(fifo, "w") as fh:
                fh.write("q1,q2,q3,q4,q5,q6\n10,20,30,40,50,60\n")
        except BrokenPipeError:
            pass

    writer = threading.Thread(target=feed, daemon=True)
    writer.start()
    err = _fail(["fk", "ur5", str(fifo)], capsys)
    assert "is a pipe, not a file" in err and "JOINTS" in err
    with open(fifo):  # let the writer finish if nothing opened the pipe
        pass
    writer.join(timeout=5)


@pytest.mark.parametrize("kind", ["floating", "planar"])
def test_a_mobile_base_joint_suggests_the_base_link(kind, tmp_path, joints3, capsys):
    body = '<link name="world"/>' + _joint("mobile", "world", "l0", kind=kind) + _chain()
    path = tmp_path / "mobile.urdf"
    path.write_text(_urdf(body))
    err = _fail(["fk", str(path), str(joints3)], capsys)
    assert f"joint mobile is {kind}" in err and "--base-link l0" in err
    assert main(["fk", str(path), str(joints3), "--base-link", "l0"]) == 0
    np.testing.assert_allclose(np.array(capsys.readouterr().out.splitlines()[1].split(","),
                                        dtype=float), [0, 0, 0.3], rtol=0, atol=1e-15)


def test_export_beside_a_gripper_names_the_tool_link_on_reading_back(tmp_path, joints3,
                                                                     capsys):
    """The patched URDF's tool link sits beside the fingers: the branching error listed
    only the fingers, not the 'tool' link the user needs."""
    urdf = _gripper(tmp_path)
    out = tmp_path / "exported.urdf"
    assert main(["export", str(urdf), "--tip-link", "l3", "--out", str(out)]) == 0
    capsys.readouterr()
    err = _fail(["fk", str(out), str(joints3)], capsys)
    assert "--tip-link" in err and "tool, f1, f2" in err  # the tip-named link first
    assert main(["fk", str(out), str(joints3), "--tip-link", "tool"]) == 0
    theirs = capsys.readouterr().out
    assert main(["fk", str(urdf), str(joints3), "--tip-link", "l3"]) == 0
    assert capsys.readouterr().out == theirs


def test_compensate_with_the_calibrated_urdf_of_an_arm_with_a_gripper(tmp_path, capsys):
    """--tip-link names the nominal URDF's chain end; the calibrated export of an arm with
    fingers could not be read at all (its default chain branches at the fingers)."""
    links = "".join(f'<link name="{n}"/>' for n in ("l0", "l1", "l2", "l3", "f1", "f2"))
    body = links + _joint("j1", "l0", "l1", xyz="0 0 0.3") + \
        _joint("j2", "l1", "l2", xyz="0.05 0 0.1", axis="0 1 0") + \
        _joint("j3", "l2", "l3", xyz="0.4 0 0", axis="0 1 0") + \
        _joint("fa", "l3", "f1", xyz="0.3 0.02 0", axis="0 1 0", kind="prismatic") + \
        _joint("fb", "l3", "f2", xyz="0.3 -0.02 0", axis="0 -1 0", kind="prismatic")
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(_urdf(body))
    meas, res, cal = tmp_path / "m.csv", tmp_path / "r.json", tmp_path / "cal.urdf"
    assert main(["simulate", str(urdf), "--tip-link", "l3", "--poses", "40", "--seed", "3",
                 "--out", str(meas), "--quiet"]) == 0
    assert main(["calibrate", str(urdf), str(meas), "--tip-link", "l3", "--out", str(res),
                 "--quiet"]) == 0
    assert main(["export", str(res), "--nominal", str(urdf), "--tip-link", "l3", "--out",
                 str(cal)]) == 0
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3\n10,20,30\n-40,25,60\n")
    outs = []
    for calibrated in (res, cal):
        out = tmp_path / f"o-{calibrated.stem}.csv"
        assert main(["compensate", str(calibrated), str(prog), "--nominal", str(urdf),
                     "--tip-link", "l3", "--out", str(out), "--quiet"]) == 0
        lines = out.read_text().splitlines()
        header = lines[0].split(",")
        outs.append(np.array([[float(v) for v in line.split(",")[:3]] for line in lines[1:]]))
        assert all(line.split(",")[header.index("converged")] == "true" for line in lines[1:])
    np.testing.assert_allclose(outs[0], outs[1], atol=1e-9)
    capsys.readouterr()


def test_a_result_of_another_chain_of_the_urdf_is_refused(tmp_path, capsys):
    """Calibrated from link_1 (5 joints), exported or compensated without --base-link: the
    6-joint chain took the result's values silently (its base frame then meant another
    frame, joint 1 stayed nominal)."""
    urdf = str(KR16)
    meas, res = tmp_path / "m.csv", tmp_path / "r.json"
    assert main(["simulate", urdf, "--base-link", "link_1", "--poses", "40", "--seed", "1",
                 "--out", str(meas), "--quiet"]) == 0
    assert main(["calibrate", urdf, str(meas), "--base-link", "link_1", "--out", str(res),
                 "--quiet"]) == 0
    prog = tmp_path / "p.csv"
    prog.write_text("q1,q2,q3,q4,q5,q6\n10,-80,60,20,50,60\n")
    out = tmp_path / "out.urdf"
    for args in (["export", str(res), "--nominal", urdf, "--out", str(out)],
                 ["fk", urdf, str(prog), "--params", str(res)],
                 ["compensate", str(res), str(prog), "--nominal", urdf, "--out",
                  str(tmp_path / "c.csv")]):
        err = _fail(args, capsys)
        assert "r.json" in err and "no values for 7 parameters" in err and "--base-link" in err
    assert not out.exists()
    assert main(["export", str(res), "--nominal", urdf, "--base-link", "link_1", "--out",
                 str(out)]) == 0
    capsys.readouterr()
