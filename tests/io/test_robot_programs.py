"""Robot programs of a pose plan (kinecal.io.programs): each language read back by a small
parser of its own, the joint values and their order recovered, one move and one wait per
pose; and the commands that write them (select-poses, plan-check)."""

from __future__ import annotations

import contextlib
import io
import re

import numpy as np
import pytest
import yaml

from kinecal.errors import InputError
from kinecal.io.programs import program_text, write_robot_program

NUM = r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?"


def parse_urscript(text: str) -> tuple[np.ndarray, list[float]]:
    """Every movej's joints (rad) and every sleep's seconds, in order."""
    moves = [[float(v) for v in m.split(",")] for m in
             re.findall(r"^\s*movej\(\[([^\]]*)\]", text, re.M)]
    waits = [float(w) for w in re.findall(rf"^\s*sleep\(({NUM})\)", text, re.M)]
    assert re.search(r"^def (\w+)\(\):$", text, re.M) and re.search(r"^end$", text, re.M)
    return np.array(moves), waits


def parse_rapid(text: str) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """Every MoveAbsJ's robot axes (deg) and external axes, every WaitTime."""
    found = re.findall(r"^\s*MoveAbsJ \[\[([^\]]*)\],\[([^\]]*)\]\]\\NoEOffs, v\d+, fine, "
                       r"tool0;$", text, re.M)
    rob = np.array([[float(v) for v in a.split(",")] for a, _ in found])
    ext = np.array([[float(v) for v in b.split(",")] for _, b in found])
    waits = [float(w) for w in re.findall(rf"^\s*WaitTime ({NUM});$", text, re.M)]
    name = re.search(r"^MODULE (\w+)$", text, re.M).group(1)
    assert text.rstrip().endswith("ENDMODULE") and "PROC main()" in text and name
    return rob, ext, waits


def parse_krl(text: str) -> tuple[list[dict[str, float]], list[float]]:
    """Every PTP's axes by name (deg / mm), every WAIT SEC."""
    moves = [{k: float(v) for k, v in re.findall(rf"([AE]\d+) ({NUM})", m)}
             for m in re.findall(r"^\s*PTP \{([^}]*)\}$", text, re.M)]
    waits = [float(w) for w in re.findall(rf"^\s*WAIT SEC ({NUM})$", text, re.M)]
    assert re.search(r"^DEF (\w+)\(\)$", text, re.M) and text.rstrip().endswith("END")
    return moves, waits


@pytest.fixture
def plan():
    rng = np.random.default_rng(3)
    return rng.uniform(-3, 3, (7, 6))


def test_urscript_round_trip(plan, tmp_path):
    path = write_robot_program(tmp_path / "check poses.script", plan, wait=1.5)
    moves, waits = parse_urscript(path.read_text())
    np.testing.assert_allclose(moves, plan, atol=5e-10)
    assert waits == [1.5] * len(plan)
    assert "def check_poses():" in path.read_text()


def test_rapid_round_trip_in_degrees(plan, tmp_path):
    path = write_robot_program(tmp_path / "plan.mod", plan)
    rob, ext, waits = parse_rapid(path.read_text())
    np.testing.assert_allclose(rob, np.degrees(plan), atol=5e-7)
    assert (ext == 9e9).all() and waits == [2.0] * len(plan)


def test_krl_round_trip_with_a_linear_axis(tmp_path):
    """Seven joints, the seventh a linear track in metres: A1..A6 in degrees, E1 in mm."""
    q = np.random.default_rng(4).uniform(-2, 2, (5, 7))
    q[:, 6] = [0.1, 0.25, 1.5, 2.0, 0.0]
    lin = [False] * 6 + [True]
    path = write_robot_program(tmp_path / "plan.src", q, prismatic=lin, length_unit="m")
    moves, waits = parse_krl(path.read_text())
    assert [sorted(m) for m in moves] == [sorted([f"A{i}" for i in range(1, 7)] + ["E1"])] * 5
    np.testing.assert_allclose([[m[f"A{i}"] for i in range(1, 7)] for m in moves],
                               np.degrees(q[:, :6]), atol=5e-7)
    np.testing.assert_allclose([m["E1"] for m in moves], q[:, 6] * 1000, atol=5e-7)
    assert waits == [2.0] * 5
    _, ext, _ = parse_rapid(program_text(tmp_path / "plan.mod", q, prismatic=lin,
                                           length_unit="m"))
    np.testing.assert_allclose(ext[:, 0], q[:, 6] * 1000, atol=5e-7)
    assert (ext[:, 1:] == 9e9).all()


def test_ros2_trajectory_round_trip(plan, tmp_path):
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
    path = write_robot_program(tmp_path / "plan.yaml", plan, joint_names=names, wait=3)
    text = path.read_text()
    msg = yaml.safe_load(text)
    assert msg["joint_names"] == names and len(msg["points"]) == len(plan)
    np.testing.assert_allclose([p["positions"] for p in msg["points"]], plan, atol=5e-10)
    times = [p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"]
             for p in msg["points"]]
    assert np.all(np.diff(times) >= 3) and all(p["velocities"] == [0.0] * 6
                                                for p in msg["points"])
    assert len(re.findall(r"^  - positions: \[[^\]]+\]$", text, re.M)) == len(plan)  # flow


def test_programs_refuse_what_a_language_cannot_say(tmp_path):
    q = np.zeros((2, 7))
    with pytest.raises(InputError, match="six revolute joints"):
        program_text(tmp_path / "a.script", q)
    with pytest.raises(InputError, match=r"\.script .*\.mod .*\.src .*\.yaml"):
        program_text(tmp_path / "a.txt", np.zeros((2, 6)))
    with pytest.raises(InputError, match="finite"):
        program_text(tmp_path / "a.mod", np.full((2, 6), np.nan))
    with pytest.raises(InputError, match="13 joints"):
        program_text(tmp_path / "a.src", np.zeros((2, 13)))


def _kinecal(*args):
    from kinecal.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main([str(a) for a in args])
    return code, err.getvalue()


@pytest.mark.parametrize("suffix", [".script", ".mod", ".src", ".yaml"])
def test_select_poses_and_plan_check_write_the_same_program_as_their_csv(suffix, tmp_path):
    """The program visits the CSV's poses in its order, whichever command wrote them."""
    from kinecal.io.csvtable import read_table

    for command, extra in (("select-poses", ["--count", "12"]), ("plan-check",
                                                                 ["--poses", "8"])):
        csv_path, prog = tmp_path / f"{command}.csv", tmp_path / f"{command}{suffix}"
        code, err = _kinecal(command, "ur5", *extra, "--out", csv_path, "--program", prog)
        assert code == 0, err
        table = read_table(csv_path, [f"q{i}" for i in range(1, 7)])
        deg = np.column_stack([table[f"q{i}"] for i in range(1, 7)])
        text = prog.read_text()
        if suffix == ".script":
            got = np.degrees(parse_urscript(text)[0])
        elif suffix == ".mod":
            got = parse_rapid(text)[0]
        elif suffix == ".src":
            got = np.array([[m[f"A{i}"] for i in range(1, 7)] for m in parse_krl(text)[0]])
        else:
            got = np.degrees([p["positions"] for p in yaml.safe_load(text)["points"]])
        np.testing.assert_allclose(got, deg, atol=1e-5)
    code, err = _kinecal("plan-check", "ur5", "--out", tmp_path / "x.csv", "--program",
                         tmp_path / "x.pdf")
    assert code == 2 and "URScript" in err and not (tmp_path / "x.csv").exists()
