"""Robot systems on the command line: a URDF tree with several --tip-link and the bundled
system files through simulate, calibrate, fk, identifiability, compensate and export (the
exported tree loaded by pinocchio), and the bad inputs: exit 2 with one line."""

import importlib.metadata
import json

import numpy as np
import pinocchio as pin
import pytest

from kinecal.cli import main
from kinecal.io.systems import load_machine

TALOS = ("talos_data/robots/talos_reduced.urdf",
         ["gripper_left_base_link", "gripper_right_base_link"])


def talos_path() -> str:
    dist = importlib.metadata.distribution("example-robot-data")
    return str(dist.locate_file(f"cmeel.prefix/share/example-robot-data/robots/{TALOS[0]}"))


def tips_args(tips):
    return [a for t in tips for a in ("--tip-link", t)]


def run(args, capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_urdf_tree_end_to_end(tmp_path, capsys):
    urdf = talos_path()
    tips = tips_args(TALOS[1])
    data, val, res = tmp_path / "d.csv", tmp_path / "v.csv", tmp_path / "r.json"
    for out, seed in ((data, 1), (val, 2)):
        code, _, err = run(["simulate", urdf, *tips, "--poses", 25, "--noise", 1e-5,
                            "--errors", "random" if seed == 1 else tmp_path / "t.json",
                            "--seed", seed, "--out", out,
                            *(["--truth-out", tmp_path / "t.json"] if seed == 1 else [])],
                           capsys)
        assert code == 0, err
    header = data.read_text().splitlines()[0].split(",")
    assert "torso_2_joint" in header and "tip" in header and "q1" not in header
    code, out, err = run(["calibrate", urdf, *tips, data, "--validate", val, "--out", res],
                         capsys)
    assert code == 0, err
    assert "per tip" in out and "system: what each chain's data identify alone" in out
    result = json.loads(res.read_text())
    for section in ("calibration", "validation"):
        assert set(result[section]["by_tip"]) == set(TALOS[1])
        for entry in result[section]["by_tip"].values():
            assert entry["after"]["rms"] < entry["before"]["rms"] / 10
    assert result["system"]["shared"][:2] == ["base.x", "base.y"]
    # fk with the result: each row on its chain, as the calibrated system computes it
    code, out, err = run(["fk", urdf, *tips, val, "--params", res], capsys)
    assert code == 0, err
    system = load_machine(urdf, tips=TALOS[1])
    from kinecal.io.result_values import parameters_from_result
    from kinecal.io.system_data import read_system_data

    p = parameters_from_result(system, res)
    v = read_system_data(val, system)
    printed = np.loadtxt(out.splitlines()[1:], delimiter=",")
    np.testing.assert_array_equal(printed, system.fk(v.q, p, v.marker)[:, :3, 3])
    # the calibrated tree, into a copy of the URDF: pinocchio reproduces every tip
    tree = tmp_path / "cal.urdf"
    code, _, err = run(["export", res, "--nominal", urdf, *tips, "--format", "urdf",
                        "--out", tree], capsys)
    assert code == 0, err
    model = pin.buildModelFromUrdf(str(tree))
    pdata = model.createData()
    cfg = pin.neutral(model)
    for k, name in enumerate(system.joint_names):
        cfg[model.joints[model.getJointId(name)].idx_q] = v.q[0, k]
    pin.framesForwardKinematics(model, pdata, cfg)
    for t, tip in enumerate(system.tips):
        T = pdata.oMf[model.getFrameId(f"{tip}_tool")].homogeneous
        np.testing.assert_allclose(T, system.fk(v.q[:1], p, np.array([t]))[0], atol=1e-12)
    assert "<mesh" in tree.read_text()  # the rest of the file kept


def test_rail_cell_from_the_bundled_data(tmp_path, capsys):
    res = tmp_path / "r.json"
    report = tmp_path / "r.html"
    code, out, err = run(["calibrate", "rail-cell", "rail-cell:tracker", "rail-cell:touches",
                          "--validate", "rail-cell:validation", "--out", res, "--report",
                          report], capsys)
    assert code == 0, err
    text = report.read_text()  # a section per chain and one for the shared part
    for title in ("Chain rail", "Chain arm", "Chain positioner", "The shared part"):
        assert f"<h2>{title}</h2>" in text
    shared = text.split("<h2>The shared part</h2>")[1].split("</section>")[0]
    assert "rail.d1" in shared and "positioner.theta1" in shared  # only the combination
    assert "0 residual rows of this chain" in text.split("<h2>Chain positioner</h2>")[1]
    result = json.loads(res.read_text())
    by_tip = result["validation"]["by_tip"]
    assert by_tip["arm"]["after"]["rms"] < 0.05 and by_tip["rail"]["after"]["rms"] < 0.05
    assert "positioner.theta1" in result["system"]["combination_only"]
    points = result["kinds"][1]["unknowns"]
    assert len(points) == 4 and {p["frame"] for p in points} == {"positioner"}
    # compensate a joint program of the arm (the rail a joint of its chain)
    prog = tmp_path / "prog.csv"
    prog.write_text("rail.q1,arm.q1,arm.q2,arm.q3,arm.q4,arm.q5,arm.q6\n"
                    "500,10,-80,90,-100,-90,0\n900,20,-70,80,-90,-80,10\n")
    out_csv = tmp_path / "comp.csv"
    code, out, err = run(["compensate", res, prog, "--nominal", "rail-cell", "--tip", "arm",
                          "--out", out_csv, "--json"], capsys)
    assert code == 0, err
    stats = json.loads(out)
    assert stats["converged"] == 2 if "converged" in stats else True
    rows = out_csv.read_text().splitlines()
    assert rows[0].startswith("rail.q1,arm.q1") and len(rows) == 3
    code, out, err = run(["identifiability", "rail-cell", "--data", "rail-cell:tracker",
                          "--data", "rail-cell:touches", "--json"], capsys)
    assert code == 0, err
    assert "positioner.theta1" in json.loads(out)["system"]["combination_only"]


def test_plan_rows_of_a_system_measure_and_calibrate(tmp_path, capsys):
    """select-poses chooses the rows (which chain, in which configuration) that identify
    the most; the plan is analysed as it is, measured with simulate --joints and
    calibrated."""
    plan, truth, data = tmp_path / "plan.csv", tmp_path / "t.json", tmp_path / "d.csv"
    code, _, err = run(["select-poses", "dual-ur5", "--count", 40, "--candidates", 200,
                        "--out", plan], capsys)
    assert code == 0, err
    rows = plan.read_text().splitlines()
    assert len(rows) == 41 and rows[0].endswith(",tip")
    assert {r.rsplit(",", 1)[1] for r in rows[1:]} == {"left", "right"}
    code, out, err = run(["identifiability", "dual-ur5", "--data", plan, "--json"], capsys)
    assert code == 0, err
    planned = json.loads(out)
    code, _, err = run(["simulate", "dual-ur5", "--joints", plan, "--truth-out", truth,
                        "--out", data], capsys)
    assert code == 0, err
    code, out, err = run(["calibrate", "dual-ur5", data, "--json"], capsys)
    assert code == 0, err
    result = json.loads(out)
    # at the solution the perturbed arms identify no less than the nominal plan said; the
    # noise-free rows are fitted to the D-H floor of near-parallel axes (random errors on
    # every parameter), far below the errors before
    assert result["rank"] >= planned["rank"]
    assert result["calibration"]["after"]["max"] < 1e-4 < result["calibration"]["before"]["rms"]


@pytest.mark.parametrize(("args", "words"), [
    (["fk", "rail-cell", "rail-cell:validation", "--tip", "arm"],
     "applies to files without a tip column"),
    (["calibrate", "rail-cell", "rail-cell:tracker", "--model-out", "m.yaml"], "system"),
    (["calibrate", "rail-cell", "rail-cell:tracker", "--method", "pso"], "stacked"),
    (["calibrate", "rail-cell", "rail-cell:tracker", "--tip", "nope"], "unknown tip"),
    (["calibrate", "ur5", "ur5-laser-tracker:random", "--tip", "a"], "robot system"),
    (["simulate", "dual-ur5", "--kind", "ballbar", "--poses", "3", "--out", "x.csv"],
     "tracker, pair or point"),
    (["export", "rail-cell", "--format", "yaml", "--out", "x.yaml"], "urdf"),
])
def test_bad_system_inputs_exit_2_with_one_line(args, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(args, capsys)
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.startswith("kinecal: error")]
    assert len(lines) == 1 and words in lines[0], err


def test_unknown_tip_link_of_a_tree(tmp_path, capsys):
    code, _, err = run(["simulate", talos_path(), "--tip-link", TALOS[1][0], "--tip-link",
                        "no_such_link", "--poses", 3, "--out", tmp_path / "x.csv"], capsys)
    assert code == 2 and "no_such_link" in err
    assert not (tmp_path / "x.csv").exists()


def test_batch_jobs_take_systems(tmp_path, capsys):
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text("jobs:\n  - {name: cell, model: rail-cell, data: [rail-cell:tracker, "
                    "rail-cell:touches], validation: rail-cell:validation}\n"
                    f"  - {{name: talos, model: {talos_path()}, tip_link: "
                    f"[{TALOS[1][0]}, {TALOS[1][1]}], data: {tmp_path / 'd.csv'}}}\n")
    code, _, err = run(["simulate", talos_path(), *tips_args(TALOS[1]), "--poses", 20,
                        "--noise", 1e-5, "--out", tmp_path / "d.csv"], capsys)
    assert code == 0, err
    code, _, err = run(["batch", jobs, "--out", tmp_path / "out", "--workers", 1], capsys)
    assert code == 0, err
    cell = json.loads((tmp_path / "out" / "cell.json").read_text())
    assert set(cell["validation"]["by_tip"]) == {"rail", "arm", "positioner"}
    talos = json.loads((tmp_path / "out" / "talos.json").read_text())
    assert set(talos["calibration"]["by_tip"]) == set(TALOS[1])


def test_angle_unit_of_a_systems_files(tmp_path, capsys):
    """--angle-unit rad reads a system's revolute columns in radians: fk of a file in
    radians equals fk of the same rows in the system's degrees."""
    deg = tmp_path / "deg.csv"
    code, _, err = run(["simulate", "dual-ur5", "--poses", 3, "--out", deg, "--quiet"], capsys)
    assert code == 0, err
    lines = deg.read_text().splitlines()
    header = lines[0].split(",")
    joints = [i for i, c in enumerate(header) if c.startswith(("left.q", "right.q"))]
    rad = tmp_path / "rad.csv"
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        for i in joints:
            if cells[i]:
                cells[i] = repr(float(np.radians(float(cells[i]))))
        out.append(",".join(cells))
    rad.write_text("\n".join(out) + "\n")
    code, in_deg, err = run(["fk", "dual-ur5", deg], capsys)
    assert code == 0, err
    code, in_rad, err = run(["fk", "dual-ur5", rad, "--angle-unit", "rad"], capsys)
    assert code == 0, err
    np.testing.assert_allclose(np.loadtxt(in_rad.splitlines()[1:], delimiter=","),
                               np.loadtxt(in_deg.splitlines()[1:], delimiter=","), atol=1e-9)
    code, _, err = run(["calibrate", "dual-ur5", deg, "--fixture", deg], capsys)
    assert code == 2 and "--fixture" in err
