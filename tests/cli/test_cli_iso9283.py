"""``kinecal iso9283``: the CSV contract, JSON against hand-computed ISO 9283 figures, joints
with a model (and a calibration result), and every bad input refused with exit 2, nothing
written."""

import csv
import json
import math

import numpy as np
import pytest

import kinecal
from kinecal.calibration.serial.simulate import simulate
from kinecal.cli import main
from kinecal.data import RepeatedPoses
from kinecal.io.measurements import write_measurements
from kinecal.metrology.iso9283 import iso9283
from kinecal.spatial import matrix_from_rpy, quaternion_from_matrix

P, N = 5, 30


def write_csv(path, header, rows):
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows([[repr(float(v)) if isinstance(v, float | np.floating) else v for v in r]
                     for r in rows])
    return path


def cartesian_test(tmp_path, seed=0):
    """5 poses x 30 cycles with orientations; commanded cells on cycle 1 only; the cycles in
    random order (the poses in order within each)."""
    rng = np.random.default_rng(seed)
    cmd = rng.uniform(-600.0, 600.0, (P, 3))
    meas = cmd[:, None] + rng.normal(0.0, 0.1, (P, 1, 3)) + rng.normal(0.0, 0.02, (P, N, 3))
    abc_c = rng.uniform(-1.0, 1.0, (P, 3))
    q_c = quaternion_from_matrix(matrix_from_rpy(abc_c))
    q_m = quaternion_from_matrix(matrix_from_rpy(abc_c[:, None] + rng.normal(0, 1e-4, (P, N, 3))))
    rows = []
    for j in range(N):
        for i in range(P):
            c = [*cmd[i], *q_c[i]] if j == 0 else [""] * 7
            rows.append([f"P{i + 1}", j + 1, *meas[i, j], *q_m[i, j], *c])
    order = (P * rng.permutation(N)[:, None] + np.arange(P)).ravel()  # cycles shuffled
    header = ["pose", "cycle", "x", "y", "z", "qw", "qx", "qy", "qz",
              "cx", "cy", "cz", "cqw", "cqx", "cqy", "cqz"]
    path = write_csv(tmp_path / "meas.csv", header, [rows[k] for k in order])
    return path, cmd, meas, q_m, q_c


def run(capsys, *args):
    code = main(["iso9283", *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_json_equals_the_standard_formulas_by_hand(tmp_path, capsys):
    path, cmd, meas, q_m, q_c = cartesian_test(tmp_path)
    code, out, err = run(capsys, path, "--json", "--pairs", "P2-P4,P1-P5")
    assert code == 0, err
    res = json.loads(out)
    assert res["cycles"] == N and res["warnings"] == []
    assert [p["pose"] for p in res["poses"]] == [f"P{i + 1}" for i in range(P)]
    for i, got in enumerate(res["poses"]):
        bary = [sum(meas[i, j, k] for j in range(N)) / N for k in range(3)]
        ap = [bary[k] - cmd[i, k] for k in range(3)]
        lj = [math.dist(meas[i, j], bary) for j in range(N)]
        lm = sum(lj) / N
        sl = math.sqrt(sum((v - lm) ** 2 for v in lj) / (N - 1))
        assert got["AP"] == pytest.approx(math.hypot(*ap), abs=1e-9)
        for k, axis in enumerate("xyz"):
            assert got[f"AP{axis}"] == pytest.approx(ap[k], abs=1e-9)
        assert got["RP"] == pytest.approx(lm + 3 * sl, abs=1e-9)
    assert [d["poses"] for d in res["distances"]] == [["P2", "P4"], ["P1", "P5"]]
    for (i, k), got in zip([(1, 3), (0, 4)], res["distances"], strict=True):
        dj = [math.dist(meas[i, j], meas[k, j]) for j in range(N)]
        dm = sum(dj) / N
        assert got["AD"] == pytest.approx(dm - math.dist(cmd[i], cmd[k]), abs=1e-9)
        sd = math.sqrt(sum((v - dm) ** 2 for v in dj) / (N - 1))
        assert got["RD"] == pytest.approx(3 * sd, abs=1e-9)
    # orientation: the same numbers as the library on the same matrices (tests/metrology
    # checks those against the formulas)
    from kinecal.spatial import matrix_from_quaternion

    lib = iso9283(RepeatedPoses(tuple(f"P{i + 1}" for i in range(P)), np.arange(1, N + 1),
                                meas, cmd, matrix_from_quaternion(q_m),
                                matrix_from_quaternion(q_c))).to_dict()
    for got, want in zip(res["poses"], lib["poses"], strict=True):
        for key in ("APa", "APb", "APc", "RPa", "RPb", "RPc"):
            assert got[key] == pytest.approx(want[key], abs=1e-9)
    code, text, _ = run(capsys, path, "--pairs", "P2-P4")
    assert code == 0 and "5 poses x 30 cycles" in text and "P2-P4" in text


def test_joints_with_a_model_give_the_commanded_pose_by_forward_kinematics(tmp_path, capsys):
    model = kinecal.load_model("ur5")
    rng = np.random.default_rng(4)
    q = rng.uniform(-2.0, 2.0, (3, model.n_joints))
    T = model.fk(q)
    offset = np.array([[0.2, -0.1, 0.05], [0.0, 0.3, 0.0], [-0.25, 0.0, 0.1]])
    signs = np.array([1.0, -1.0] * 3)  # symmetric scatter: barycentre = commanded + offset
    qw = quaternion_from_matrix(T[:, :3, :3])
    rows = []
    for j in range(6):
        for i in range(3):
            xyz = T[i, :3, 3] + offset[i] + 0.01 * signs[j] * np.array([0.0, 0.0, 1.0])
            rows.append([f"p{i}", j, *xyz, *qw[i], *np.degrees(q[i])])
    path = write_csv(tmp_path / "joints.csv", ["pose", "cycle", "x", "y", "z", "qw", "qx",
                                               "qy", "qz", *(f"q{k}" for k in range(1, 7))],
                     rows)
    code, out, err = run(capsys, path, "--model", "ur5", "--json")
    assert code == 0, err
    res = json.loads(out)
    for i, got in enumerate(res["poses"]):
        np.testing.assert_allclose([got["APx"], got["APy"], got["APz"]], offset[i], atol=1e-9)
        assert got["RP"] == pytest.approx(0.01, abs=1e-9)
        for key in ("APa", "APb", "APc", "RPa", "RPb", "RPc"):
            assert abs(got[key]) < 1e-6  # measured orientation = commanded, round-off only


def test_params_gives_after_and_nominal_before_like_the_calibrated_model(tmp_path, capsys):
    """--params RESULT: AP by the calibrated model equals a run with --model-out's model,
    and the 'before' AP equals a run with the nominal model."""
    model = kinecal.load_model("ur5")
    sim = simulate(model, 60, errors="random", noise=0.01, rng=5)
    write_measurements(tmp_path / "cal.csv", sim.data, model)
    assert main(["calibrate", "ur5", str(tmp_path / "cal.csv"), "--quiet", "--out",
                 str(tmp_path / "r.json"), "--model-out", str(tmp_path / "c.yaml")]) == 0
    capsys.readouterr()
    rng = np.random.default_rng(6)
    q = rng.uniform(-2.0, 2.0, (4, model.n_joints))
    true_xyz = model.positions(q, sim.true_params)
    rows = [[f"P{i + 1}", j + 1, *(true_xyz[i] + rng.normal(0, 0.01, 3)), *np.degrees(q[i])]
            for j in range(5) for i in range(4)]
    path = write_csv(tmp_path / "iso.csv", ["pose", "cycle", "x", "y", "z",
                                            *(f"q{k}" for k in range(1, 7))], rows)
    runs = {}
    for name, extra in (("params", ["--model", "ur5", "--params", tmp_path / "r.json"]),
                        ("calibrated", ["--model", tmp_path / "c.yaml"]),
                        ("nominal", ["--model", "ur5"])):
        code, out, err = run(capsys, path, "--json", *extra)
        assert code == 0, err
        runs[name] = json.loads(out)
    ap = {k: np.array([p["AP"] for p in v["poses"]]) for k, v in runs.items()}
    before = np.array([p["AP"] for p in runs["params"]["before"]["poses"]])
    np.testing.assert_allclose(ap["params"], ap["calibrated"], atol=1e-6)
    np.testing.assert_allclose(before, ap["nominal"], atol=1e-9)
    assert ap["params"].max() < 0.1 < ap["nominal"].min()  # the calibration shows


def _rows(cycles=3, poses=3, skip=(), dup=(), blank_pose=None):
    rows = []
    for c in range(1, cycles + 1):
        for i in range(poses):
            if (i, c) in skip:
                continue
            cmd = ["", "", ""] if (c > 1 or i == blank_pose) else [10.0 * i, 1.0, 2.0]
            rows.append([f"P{i + 1}", c, 10.0 * i + 0.01 * c, 1.0, 2.0, *cmd])
            if (i, c) in dup:
                rows.append([f"P{i + 1}", c, 10.0 * i, 1.0, 2.0, "", "", ""])
    return rows


HEAD = ["pose", "cycle", "x", "y", "z", "cx", "cy", "cz"]


@pytest.mark.parametrize(("rows", "header", "args", "reason"), [
    (_rows(cycles=1), HEAD, [], "1 cycle (cycle 1): expected at least 2 cycles"),
    (_rows(skip={(2, 2)}), HEAD, [], "cycles of different lengths: cycle 2 has 2 of the 3 "
     "poses (missing: P3)"),
    (_rows(blank_pose=1), HEAD, [], "pose 'P2' has no commanded values"),
    (_rows(dup={(0, 2)}), HEAD, [], "duplicate cycle number: pose 'P1' has cycle 2 on rows"),
    ([r if r[:2] != ["P1", 3] else [*r[:5], 0.5, 1.0, 2.0] for r in _rows()], HEAD, [],
     "commanded cx, cy, cz differ from row 1"),
    ([r[:5] for r in _rows()], HEAD[:5], [], "no commanded pose: expected columns cx, cy, cz"),
    ([[*r, 1.0] for r in _rows()], [*HEAD, "qw"], [], "qw without the others"),
    ([[*r[:5], 0.1] for r in _rows()], [*HEAD[:5], "q1"], [], "joint columns without a model"),
    (_rows(), HEAD, ["--pairs", "P1-P9"], "'P1-P9': expected two different poses"),
    (_rows(), HEAD, ["--model", "ur5"], "both commanded columns cx, cy, cz and --model"),
    ([[*r[:2], "x", *r[3:]] for r in _rows()], HEAD, [], "row 1"),
])
def test_bad_input_exits_2_with_the_reason_and_writes_nothing(tmp_path, capsys, rows, header,
                                                              args, reason):
    path = write_csv(tmp_path / "bad.csv", header, rows)
    report = tmp_path / "r.html"
    code, out, err = run(capsys, path, "--report", report, *args)
    assert code == 2, err
    assert reason in err and err.count("\n") == 1 and out == ""
    assert not report.exists()


def test_record_options_need_a_report(tmp_path, capsys):
    path = write_csv(tmp_path / "ok.csv", HEAD, _rows())
    code, _, err = run(capsys, path, "--operator", "me")
    assert code == 2 and "option --operator: applies to --report only" in err
    code, out, err = run(capsys, path, "--json")  # the same file is fine
    assert code == 0 and json.loads(out)["poses"][0]["pose"] == "P1"


def test_reader_orders_poses_by_appearance_and_cycles_by_number(tmp_path):
    """The reader alone: cycles sorted, poses in order of appearance."""
    from kinecal.io.repeatability import read_repeatability

    rows = _rows()
    path = write_csv(tmp_path / "ok.csv", HEAD, rows[::-1])
    data = read_repeatability(path)
    assert data.labels == ("P3", "P2", "P1") and list(data.cycles) == [1, 2, 3]
    np.testing.assert_allclose(data.measured[2, :, 0], [0.01, 0.02, 0.03])
    np.testing.assert_allclose(data.commanded[1], [10.0, 1.0, 2.0])
