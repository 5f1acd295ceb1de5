"""Universal Robots files: ``export --format ur-kinematics`` checked through
ur_description's own xacro (the ``ur_description`` fixture of tests/io/conftest.py),
``import calibration.conf`` against the nominal D-H plus the deltas, bad files refused."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import yaml

from kinecal.cli import main
from kinecal.io.models import load_model, save_model

SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: UR5 nominal D-H (Universal Robots' table, metres): d1, a2, a3, d4, d5, d6
UR5 = (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823)


def _load(name):
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


dh_flange = _load("test_ur_calibration_files").dh_flange  # the standard D-H chain, on its own


def _flange_params(model):
    p = model.nominal
    p[model.index(["tool.x", "tool.y", "tool.z"])] = 0.0
    return p


def _perturbed_ur5(rng, big=False):
    model = load_model("ur5")
    p = model.nominal
    for i in range(1, 7):
        names = ["theta", "d"] + (["a", "alpha"] if i < 6 else [])
        for n in names:
            k = model.index([f"{n}{i}"])[0]
            p[k] += rng.normal(0, 0.5 if n in ("d", "a") else 0.002)
    if big:  # a factory calibration moves d2..d4 metres along the parallel axes
        p[model.index(["d2", "d3", "d4"])] += [4000.0, -4500.0, 500.0]
        p[model.index(["alpha2", "alpha3"])] += [0.001, -0.002]
    return model.with_params(p, name="ur5-perturbed")


@pytest.mark.parametrize("big", [False, True])
def test_ur_kinematics_gives_the_flange_on_300_configurations(tmp_path, capsys,
                                                             ur_description, big):
    """The exported file through ur_description's xacro: tool0 in base is the model's
    flange to 1e-9 mm, also when d2..d4 moved metres."""
    model = _perturbed_ur5(np.random.default_rng(11), big)
    path = tmp_path / "m.yaml"
    save_model(model, path)
    out = tmp_path / "default_kinematics.yaml"
    assert main(["export", str(path), "--format", "ur-kinematics", "--out", str(out)]) == 0
    assert "reference ur5" in capsys.readouterr().err
    kin = yaml.safe_load(out.read_text())["kinematics"]
    assert set(kin) == {*SEGMENTS, "hash"} and str(kin["hash"]).startswith("kinecal_")
    q = np.random.default_rng(5).uniform(-2 * np.pi, 2 * np.pi, (300, 6))
    ours = model.fk(q, _flange_params(model))  # mm
    theirs = ur_description.tool0("ur5", q, out)  # m
    assert np.abs(theirs[:, :3, 3] * 1000.0 - ours[:, :3, 3]).max() < 1e-9  # mm
    assert np.abs(theirs[:, :3, :3] - ours[:, :3, :3]).max() < 1e-12
    # the link frames stay next to ur_description's nominal ones (meshes land on the links)
    nominal = {"shoulder": (0, 0, UR5[0]), "upper_arm": (0, 0, 0), "forearm": (UR5[1], 0, 0),
               "wrist_1": (UR5[2], 0, UR5[3]), "wrist_2": (0, -UR5[4], 0),
               "wrist_3": (0, UR5[5], 0)}
    for seg, xyz in nominal.items():
        got = np.array([kin[seg][c] for c in "xyz"])
        assert np.abs(got - xyz).max() < 0.01, (seg, got)


def test_nominal_export_is_ur_descriptions_table(tmp_path):
    out = tmp_path / "k.yaml"
    assert main(["export", "ur5", "--format", "ur-kinematics", "--out", str(out)]) == 0
    kin = yaml.safe_load(out.read_text())["kinematics"]
    assert kin["shoulder"]["z"] == UR5[0] and kin["forearm"]["x"] == UR5[1]
    assert (kin["wrist_1"]["x"], kin["wrist_1"]["z"]) == (UR5[2], UR5[3])
    assert kin["wrist_2"]["y"] == -UR5[4] and kin["wrist_3"]["y"] == UR5[5]
    assert kin["upper_arm"]["roll"] == np.pi / 2 and kin["wrist_2"]["roll"] == np.pi / 2


def test_ur_kinematics_refuses_what_ur_description_cannot_carry(tmp_path, capsys):
    model = load_model("ur5")
    p = model.nominal
    p[model.index(["a6"])] = 0.5
    path = tmp_path / "m.yaml"
    save_model(model.with_params(p), path)
    out = tmp_path / "k.yaml"
    assert main(["export", str(path), "--format", "ur-kinematics", "--out", str(out)]) == 2
    assert "a6 = 0.5 mm" in capsys.readouterr().err and not out.exists()
    assert main(["export", "irb120", "--format", "ur-kinematics", "--out", str(out)]) == 2
    assert "UR-type chain" in capsys.readouterr().err and not out.exists()


CONF = """# UR controller calibration (test data)
[mounting]
calibration_status = 2 # Linearised
delta_theta = [ {theta} ]
delta_a = [ {a} ]
delta_d = [ {d} ]
delta_alpha = [ {alpha} ]
joint_checksum = [ 1, 2, 3, 4, 5, 6 ]
"""


def _conf(deltas, n=6):
    cols = {k: ", ".join(repr(float(v)) for v in deltas[:n, c])
            for c, k in enumerate(("theta", "a", "d", "alpha"))}
    return CONF.format(**cols)


def test_import_calibration_conf_then_fk_is_nominal_plus_deltas(tmp_path, capsys,
                                                                 ur_description):
    rng = np.random.default_rng(4)
    # like a controller's: d2..d4 metres along the parallel axes (their sum small),
    # theta2..theta4 compensating, a6 and alpha6 zero
    deltas = np.c_[rng.normal(0, 1e-3, 6), rng.normal(0, 1e-4, 6), rng.normal(0, 1e-4, 6),
                   rng.normal(0, 1e-3, 6)]
    deltas[1:4, 2] += [2.0, -2.5, 0.5]
    deltas[1:4, 0] += [0.06, -0.19, 0.13]
    deltas[5, [1, 3]] = 0.0
    conf = tmp_path / "calibration.conf"
    conf.write_text(_conf(deltas))
    out = tmp_path / "model.yaml"
    assert main(["import", str(conf), "--robot", "ur5", "--out", str(out)]) == 0
    q = np.random.default_rng(9).uniform(-np.pi, np.pi, (50, 6))
    joints = tmp_path / "q.csv"
    joints.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(repr(float(v)) for v in row)
                                                       for row in np.degrees(q)) + "\n")
    capsys.readouterr()
    assert main(["fk", str(out), str(joints), "--pose"]) == 0
    fk = np.loadtxt(capsys.readouterr().out.splitlines()[1:], delimiter=",")
    d1, a2, a3, d4, d5, d6 = UR5
    nominal = np.c_[np.zeros(6), [0, a2, a3, 0, 0, 0], [d1, 0, 0, d4, d5, d6],
                    [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]]
    truth = dh_flange(nominal + deltas, q)
    # fk prints 6 decimals (mm)
    np.testing.assert_allclose(fk[:, :3], truth[:, :3, 3] * 1000.0, rtol=0, atol=1e-6)
    # and the export of that model reproduces the controller's kinematics through
    # ur_description's xacro, although d2..d4 moved metres
    kin = tmp_path / "dk.yaml"
    assert main(["export", str(out), "--format", "ur-kinematics", "--out", str(kin)]) == 0
    got = ur_description.tool0("ur5", q, kin)  # m
    ours = load_model(out).fk(q)  # mm
    assert np.abs(got[:, :3, 3] * 1000.0 - ours[:, :3, 3]).max() < 1e-9  # mm
    assert np.abs(got[:, :3, :3] - ours[:, :3, :3]).max() < 1e-12
    assert np.abs(got[:, :3, 3] - truth[:, :3, 3]).max() < 1e-12  # m


@pytest.mark.parametrize(("text", "robot", "expected"), [
    ("five", "ur5", "delta_d: expected 6 values (one per joint), got 5"),
    ("ok", "ur7", "unknown robot 'ur7'; expected one of ur3, ur3e, ur5"),
    ("[other]\nx = 1\n", "ur5", "not a UR calibration.conf: expected a [mounting] section"),
    ("nan", "ur5", "'nan' is not a finite number"),
])
def test_bad_calibration_conf_exit_2_and_nothing_written(tmp_path, capsys, text, robot,
                                                        expected):
    deltas = np.full((6, 4), 1e-3)
    if text == "five":
        body = _conf(deltas).replace(_conf(deltas).splitlines()[5],
                                     "delta_d = [ 0.1, 0.2, 0.3, 0.4, 0.5 ]")
    elif text == "ok":
        body = _conf(deltas)
    elif text == "nan":
        body = _conf(deltas).replace("delta_a = [ 0.001", "delta_a = [ nan")
    else:
        body = text
    conf = tmp_path / "calibration.conf"
    conf.write_text(body)
    out = tmp_path / "model.yaml"
    assert main(["import", str(conf), "--robot", robot, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1
    assert not out.exists()
