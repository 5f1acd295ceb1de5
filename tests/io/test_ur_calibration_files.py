"""UR controllers' calibration files as they are: the three sets of Universal Robots'
ur_calibration tests (tests/data/ur_calibration, Apache-2.0) and files made here the way a
controller makes them (the exact standard D-H table of a slightly imperfect arm, whose
nearly parallel axes put the common normals hundreds of metres out), imported, checked
against the D-H sum, the source's expected flange positions and, exported, through
ur_description's own xacro (the ``ur_description`` fixture of tests/io/conftest.py), and
judged by the geometry they give (a wrong --robot warns)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from kinecal.cli import main
from kinecal.io.models import load_model
from kinecal.io.ur.conf import read_calibration_conf

DATA = Path(__file__).resolve().parents[1] / "data" / "ur_calibration"
#: d1, a2, a3, d4, d5, d6 (m), Universal Robots' published D-H tables, written here
NOMINAL = {"ur3": (0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819),
           "ur5": (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
           "ur10": (0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
           "ur10e": (0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655)}
_WARNING = re.compile(r"^kinecal: warning: .+ \[([a-z0-9-]+)\]$")


def nominal(robot: str, alpha90: float = np.pi / 2) -> np.ndarray:
    """(6, 4) theta, a, d, alpha of a UR type."""
    d1, a2, a3, d4, d5, d6 = NOMINAL[robot]
    return np.c_[np.zeros(6), [0, a2, a3, 0, 0, 0], [d1, 0, 0, d4, d5, d6],
                 [alpha90, 0, 0, alpha90, -alpha90, 0]]


def _T(R=np.eye(3), p=(0.0, 0.0, 0.0)):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def _R(axis, a):
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i] = R[j, j] = c
    R[i, j], R[j, i] = -s, s
    return R


def dh_link(theta, a, d, alpha):
    return _T(_R(2, theta)) @ _T(p=(0, 0, d)) @ _T(p=(a, 0, 0)) @ _T(_R(0, alpha))


def dh_flange(table, q) -> np.ndarray:
    """Standard D-H flange poses (N, 4, 4), written here on its own."""
    out = []
    for qi in np.atleast_2d(q):
        T = np.eye(4)
        for (theta, a, d, alpha), angle in zip(table, qi, strict=True):
            T = T @ dh_link(theta + angle, a, d, alpha)
        out.append(T)
    return np.array(out)


# ---- a controller's file, made the way a controller makes it


class ImperfectArm:
    """A UR whose links carry small errors (a pose per link, ~`mm` and ~`mrad`), and the
    exact standard D-H table of it: each frame's z on the next joint's axis, x along the
    common normal of consecutive axes (so nearly parallel axes put it far out)."""

    def __init__(self, robot: str, seed: int, mm: float = 0.3, mrad: float = 0.5):
        rng = np.random.default_rng(seed)
        self.robot = robot
        self.nominal = nominal(robot)
        self.errors = []
        for i in range(6):
            if i == 5:  # the flange sits on the last axis (a6 = alpha6 = 0 on a UR)
                E = _T(_R(2, rng.normal(0, mrad / 1000)), (0, 0, rng.normal(0, mm / 1000)))
            else:
                w = rng.normal(0, mrad / 1000, 3)
                E = _T(_R(2, w[2]) @ _R(1, w[1]) @ _R(0, w[0]), rng.normal(0, mm / 1000, 3))
            self.errors.append(E)

    def flange(self, q) -> np.ndarray:
        out = []
        for qi in np.atleast_2d(q):
            T = np.eye(4)
            for (theta, a, d, alpha), E, angle in zip(self.nominal, self.errors, qi,
                                                      strict=True):
                T = T @ dh_link(theta + angle, a, d, alpha) @ E
            out.append(T)
        return np.array(out)

    def dh(self) -> np.ndarray:
        """The exact standard D-H table (theta, a, d, alpha) of the arm at q = 0."""
        frames, T = [], np.eye(4)
        for row, E in zip(self.nominal, self.errors, strict=True):
            T = T @ dh_link(*row) @ E
            frames.append(T)  # z: the next joint's axis (the flange's z for the last)
        table, O, x, z = [], np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
        for i, F in enumerate(frames):
            P, u = F[:3, 3], F[:3, 2]
            if i == 5:
                xi, Oi = F[:3, 0], P
                s = float((P - O) @ z)
            else:
                n = np.cross(z, u)
                xi = n / np.linalg.norm(n) * (np.sign(self.nominal[i, 3]) or 1.0)
                s, t = np.linalg.lstsq(np.c_[z, -u], P - O, rcond=None)[0]
                Oi = P + t * u
            a = float((Oi - (O + s * z)) @ xi)
            theta = np.arctan2(np.cross(x, xi) @ z, x @ xi)
            alpha = np.arctan2(np.cross(z, u) @ xi, z @ u)
            table.append((theta, a, s, alpha))
            O, x, z = Oi, xi, u
        return np.array(table)


def conf_text(deltas: np.ndarray) -> str:
    keys = ("delta_theta", "delta_a", "delta_d", "delta_alpha")
    return "[mounting]\n" + "".join(
        f"{k} = [ {', '.join(repr(float(v)) for v in deltas[:, c])} ]\n"
        for c, k in enumerate(keys))


def run(argv, capsys):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    codes = [m.group(1) for m in map(_WARNING.match, err.splitlines()) if m]
    return code, codes, err


def test_the_made_files_are_what_a_controller_writes():
    """The generator itself: its D-H table gives the imperfect arm's flange exactly, with
    d2..d4 hundreds of metres out, cancelling (as the real sets have them)."""
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (200, 6))
    for robot, seed in (("ur5", 1), ("ur10e", 2), ("ur3", 3)):
        arm = ImperfectArm(robot, seed)
        table = arm.dh()
        got, want = dh_flange(table, q), arm.flange(q)
        assert np.abs(got[:, :3, 3] - want[:, :3, 3]).max() < 1e-9  # m
        assert np.abs(got[:, :3, :3] - want[:, :3, :3]).max() < 1e-9
        deltas = table - nominal(robot)
        assert np.abs(deltas[1:4, 2]).max() > 50.0  # m, as controllers' files have them
        assert abs(deltas[1:4, 2].sum()) < 0.5 * np.abs(deltas[1:4, 2]).max()
        off = np.linalg.norm(want[:, :3, 3] - dh_flange(nominal(robot), q)[:, :3, 3], axis=1)
        assert 1e-4 < off.max() < 5e-3  # the arm is a few mm off the nominal


# ---- the real sets


SETS = [("set1.conf", "ur10"), ("set2.conf", "ur10"), ("set3.conf", "ur10"),
        ("set3.conf", "ur10e")]


@pytest.mark.parametrize(("name", "robot"), SETS)
def test_real_controller_sets_import_exactly_and_cleanly(tmp_path, capsys, name, robot):
    """Were refused ("delta_d: -446.027 is beyond 100 m", "delta_theta: 7.12936 is beyond
    6.283 rad"); now imported without a warning, the model's flange the D-H sum's."""
    out = tmp_path / "model.yaml"
    code, codes, err = run(["import", DATA / name, "--robot", robot, "--out", out], capsys)
    assert code == 0 and codes == [], err
    deltas = read_calibration_conf(DATA / name)
    model = load_model(out)
    q = np.random.default_rng(2).uniform(-2 * np.pi, 2 * np.pi, (300, 6))
    truth = dh_flange(nominal(robot) + deltas, q)
    got = model.fk(q)
    assert np.abs(got[:, :3, 3] - truth[:, :3, 3] * 1000.0).max() < 1e-9  # mm
    assert np.abs(got[:, :3, :3] - truth[:, :3, :3]).max() < 1e-12
    # what it prints is the geometry: the flange a few mm from the nominal's
    mm = float(re.search(r"the flange within ([0-9.]+) mm", err).group(1))
    off = np.linalg.norm(truth[:, :3, 3] - dh_flange(nominal(robot), q)[:, :3, 3], axis=1)
    assert off.max() * 1000.0 <= mm + 1e-3 and mm < 10.0


@pytest.mark.parametrize(("name", "robot"), SETS)
def test_export_of_a_real_set_is_exact_through_ur_descriptions_xacro(tmp_path, capsys,
                                                                      ur_description, name,
                                                                      robot):
    """ur_description's xacro of the exported file gives the imported model's flange to
    1e-9 mm, and the D-H sum's, although d2..d4 are hundreds of metres."""
    model = tmp_path / "model.yaml"
    assert main(["import", str(DATA / name), "--robot", robot, "--out", str(model)]) == 0
    kin_file = tmp_path / "kin.yaml"
    code, codes, _ = run(["export", model, "--format", "ur-kinematics", "--out", kin_file],
                         capsys)
    assert code == 0 and codes == [] and f"next to the nominal {robot}'s" in \
        kin_file.read_text()
    kin = yaml.safe_load(kin_file.read_text())["kinematics"]
    q = np.random.default_rng(3).uniform(-2 * np.pi, 2 * np.pi, (300, 6))
    truth = dh_flange(nominal(robot) + read_calibration_conf(DATA / name), q)
    got = ur_description.tool0(robot, q, kin_file)  # m
    ours = load_model(model).fk(q)  # mm
    assert np.abs(got[:, :3, 3] * 1000.0 - ours[:, :3, 3]).max() < 1e-9  # mm
    assert np.abs(got[:, :3, :3] - ours[:, :3, :3]).max() < 1e-12
    assert np.abs(got[:, :3, 3] - truth[:, :3, 3]).max() < 1e-12  # m: 1e-9 mm
    assert np.abs(got[:, :3, :3] - truth[:, :3, :3]).max() < 1e-12
    # the link frames next to the nominal arm's although d2..d4 are hundreds of metres
    d1, a2, a3, d4, d5, d6 = NOMINAL[robot]
    near = {"shoulder": (0, 0, d1), "upper_arm": (0, 0, 0), "forearm": (a2, 0, 0),
            "wrist_1": (a3, 0, d4), "wrist_2": (0, -d5, 0), "wrist_3": (0, d6, 0)}
    for seg, xyz in near.items():
        assert np.abs(np.array([kin[seg][c] for c in "xyz"]) - xyz).max() < 0.01, seg


#: ur_calibration_test.cpp's ur10_fw_kinematics_real: joints (rad) and the flange position
#: (m) of the simulated UR10, whose alpha of +-pi/2 is reported as +-1.570796327
SIMULATED = [
    ([-1.6007002035724084976209269370884, -1.7271001974688928726209269370884,
      -2.2029998938189905288709269370884, -0.80799991289247685699592693708837,
      1.59510004520416259765625, -0.03099996248354131012092693708837],
     [-0.179925914147547, -0.606869755162764, 0.230789102067257]),
    ([1.32645022869110107421875, 2.426007747650146484375, 5.951572895050048828125,
      1.27409040927886962890625, -0.54105216661562138824592693708837,
      0.122173048555850982666015625],
     [0.39922988003280424074148413637886, 0.59688365069340565405298093537567,
      -0.6677819040276375961440180617501]),
]


def test_flange_positions_of_urs_own_test(tmp_path, capsys):
    """The simulated UR10 as a calibration.conf (alpha deltas of 1.570796327 - pi/2): the
    imported model gives the source's expected positions to 1e-15 m, as its test asks."""
    deltas = np.zeros((6, 4))
    deltas[:, 3] = nominal("ur10", 1.570796327)[:, 3] - nominal("ur10")[:, 3]
    conf = tmp_path / "calibration.conf"
    conf.write_text(conf_text(deltas))
    out = tmp_path / "ur10.yaml"
    assert main(["import", str(conf), "--robot", "ur10", "--out", str(out)]) == 0
    model = load_model(out)
    for q, xyz in SIMULATED:
        np.testing.assert_allclose(model.positions(np.array(q)) / 1000.0, [xyz], rtol=0,
                                   atol=1e-15)
    # and ur10_fw_kinematics_ideal's closed forms, on the bundled ur10
    d1, a2, a3, d4, d5, d6 = NOMINAL["ur10"]
    ur10 = load_model("ur10")
    np.testing.assert_allclose(ur10.positions(np.zeros(6)) / 1000.0,
                               [[a2 + a3, -(d4 + d6), d1 - d5]], rtol=0, atol=1e-15)
    q = [np.pi / 2, -np.pi / 4, np.pi / 2, -np.pi / 4, 0, 0]
    r = np.sqrt(2.0)
    np.testing.assert_allclose(ur10.positions(np.array(q)) / 1000.0,
                               [[d4 + d6, a2 / r + a3 / r, d1 - a2 / r + a3 / r - d5]],
                               rtol=0, atol=1e-12)


# ---- files made here


@pytest.mark.parametrize(("robot", "seed", "turns"), [("ur5", 4, 0), ("ur10e", 5, 1),
                                                      ("ur3", 6, -2)])
def test_made_files_with_cancelling_offsets_and_whole_turns(tmp_path, capsys, ur_description,
                                                            robot, seed, turns):
    """Any controller-like file imports without a warning and reproduces the arm; whole
    turns added to delta_theta (beyond 2 pi) change nothing; its export through
    ur_description's xacro is the model to 1e-9 mm."""
    arm = ImperfectArm(robot, seed)
    deltas = arm.dh() - nominal(robot)
    deltas[1:4, 0] += 2 * np.pi * turns * np.array([1, -1, 1])
    conf = tmp_path / "calibration.conf"
    conf.write_text(conf_text(deltas))
    out = tmp_path / "m.yaml"
    code, codes, err = run(["import", conf, "--robot", robot, "--out", out], capsys)
    assert code == 0 and codes == [], err
    q = np.random.default_rng(7).uniform(-np.pi, np.pi, (200, 6))
    got = load_model(out).fk(q)
    want = arm.flange(q)
    assert np.abs(got[:, :3, 3] - want[:, :3, 3] * 1000.0).max() < 1e-6  # mm
    kin = tmp_path / "kin.yaml"
    assert main(["export", str(out), "--format", "ur-kinematics", "--out", str(kin)]) == 0
    back = ur_description.tool0(robot, q, kin)  # m
    assert np.abs(back[:, :3, 3] * 1000.0 - got[:, :3, 3]).max() < 1e-9  # mm
    assert np.abs(back[:, :3, :3] - got[:, :3, :3]).max() < 1e-12


def test_a_ur5_file_as_ur10_warns_and_names_the_type(tmp_path, capsys):
    """Was silently accepted: the deltas of a UR5 added to a UR10 make no arm."""
    arm = ImperfectArm("ur5", 8)
    conf = tmp_path / "calibration.conf"
    conf.write_text(conf_text(arm.dh() - nominal("ur5")))
    out = tmp_path / "m.yaml"
    code, codes, err = run(["import", conf, "--robot", "ur10", "--out", out], capsys)
    assert code == 0 and codes == ["ur-conf-implausible"]
    assert "they fit a ur5 (" in err and "ur10's flange by up to" in err
    # and the right type is clean
    code, codes, _ = run(["import", conf, "--robot", "ur5", "--out", tmp_path / "ok.yaml"],
                         capsys)
    assert code == 0 and codes == []


def test_export_robot_of_another_type_warns(tmp_path, capsys):
    """export --robot ur10 of a UR5 model was silent; the model's own type is clean."""
    for source in ("ur5", "ur5e"):
        code, codes, err = run(["export", source, "--format", "ur-kinematics", "--robot",
                                "ur10", "--out", tmp_path / f"{source}.yaml"], capsys)
        assert code == 0 and codes == ["ur-kinematics-not-ur"], err
        assert "is no ur10" in err and f"give --robot {source}" in err
    code, codes, _ = run(["export", "ur5", "--format", "ur-kinematics", "--robot", "ur5",
                          "--out", tmp_path / "same.yaml"], capsys)
    assert code == 0 and codes == []
    # a real ur10e calibration exported as a ur10e is clean, as a ur5e it warns
    model = tmp_path / "set3.yaml"
    assert main(["import", str(DATA / "set3.conf"), "--robot", "ur10e", "--out",
                 str(model)]) == 0
    code, codes, _ = run(["export", model, "--format", "ur-kinematics", "--robot", "ur5e",
                          "--out", tmp_path / "k.yaml"], capsys)
    assert codes == ["ur-kinematics-not-ur"]


@pytest.mark.parametrize(("change", "words"), [
    ("mm", ("more than the arm's reach", "another unit")),
    ("huge", ("1e+300 is beyond", "no useful precision")),
])
def test_files_that_are_no_calibration_are_refused(tmp_path, capsys, change, words):
    deltas = read_calibration_conf(DATA / "set1.conf")
    if change == "mm":  # lengths written in millimetres
        deltas[:, 1:3] *= 1000.0
    else:
        deltas[2, 0] = 1e300
    conf = tmp_path / "calibration.conf"
    conf.write_text(conf_text(deltas))
    out = tmp_path / "m.yaml"
    code, _, err = run(["import", conf, "--robot", "ur10", "--out", out], capsys)
    assert code == 2 and all(w in err for w in words), err
    assert not out.exists()
