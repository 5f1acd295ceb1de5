"""Several measurement files of any kinds on the command line (issue 25): simulate each
kind, calibrate a mix (JSON, model file), plan a mix with identifiability, and the bad
inputs of the issue: exit 2 with one line, or a named warning."""

import json

import numpy as np
import pytest

import kinecal
from kinecal.cli import main
from kinecal.io.kinds import read_gauge, read_kind, write_gauge


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A ballbar and a fixed-point file of one hidden IRB-120 (simulated by the CLI)."""
    d = tmp_path_factory.mktemp("kinds")
    assert main(["simulate", "irb120", "--kind", "ballbar", "--poses", "16", "--noise",
                 "0.002", "--seed", "1", "--out", str(d / "bb.csv"), "--truth-out",
                 str(d / "truth.json"), "--quiet"]) == 0
    assert main(["simulate", "irb120", "--kind", "point", "--poses", "6", "--noise", "0.01",
                 "--errors", str(d / "truth.json"), "--seed", "2", "--out",
                 str(d / "pt.csv"), "--sigma-column", "--quiet"]) == 0
    return d


def _csv(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(str(c) for c in r) for r in rows)
                    + "\n", encoding="utf-8")
    return str(path)


def test_simulated_files_read_back_with_their_kind(files):
    m = kinecal.load_model("irb120")
    bb, pt = read_kind(files / "bb.csv", m), read_kind(files / "pt.csv", m)
    assert (bb.kind, pt.kind) == ("ballbar", "point")
    assert bb.group_names == ("P1", "P2") and len(bb) == 32 and bb.distance.min() > 50
    assert pt.sigma is not None and np.allclose(pt.sigma, 0.01)
    write_gauge(files / "copy.csv", pt, m)
    back = read_gauge(files / "copy.csv", m)
    np.testing.assert_array_equal(back.q, pt.q)
    assert back.group_names == pt.group_names and np.array_equal(back.group, pt.group)


def test_calibrate_a_mix_writes_json_and_a_model(files, capsys):
    out, model = files / "r.json", files / "cal.yaml"
    code = main(["calibrate", "irb120", str(files / "bb.csv"), str(files / "pt.csv"),
                 "--sigma", "bb.csv=0.002", "--out", str(out), "--model-out", str(model),
                 "--quiet"])
    assert code == 0, capsys.readouterr().err
    r = json.loads(out.read_text())
    kinds = {k["kind"]: k for k in r["kinds"]}
    assert kinds["ballbar"]["sigma_source"] == "stated"
    assert kinds["point"]["sigma_source"] == "stated"  # its sigma column
    assert kinds["ballbar"]["after"]["rms"] < 0.01 < kinds["ballbar"]["before"]["rms"]
    assert r["not_seen"] == ["translation z", "rotation z"]
    assert kinecal.load_model(str(model)).name.endswith("calibrated")


def test_identifiability_plans_a_mix(files, capsys):
    code = main(["identifiability", "irb120", "--data", str(files / "bb.csv"), "--data",
                 str(files / "pt.csv"), "--json"])
    assert code == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["not_seen"] == ["translation z", "rotation z"]
    assert {"theta1", "d1"} <= set(rep["unidentifiable"])
    assert [k["unknowns"] for k in rep["kinds"]] == [6, 12]
    code = main(["identifiability", "irb120", "--data", str(files / "pt.csv"), "--json"])
    assert "scale" in json.loads(capsys.readouterr().out)["not_seen"]


def test_bad_inputs_exit_2_or_warn_by_name(files, capsys, tmp_path):
    q = "q1,q2,q3,q4,q5,q6"
    rng = np.random.default_rng(0)
    rows = np.round(rng.uniform(-60, 60, (10, 6)), 3).tolist()
    cases = {
        "pivot 'B' has 1 row": _csv(tmp_path / "bb1.csv", f"{q},pivot,distance",
                                    [r + ["A", 200] for r in rows[:9]] + [rows[9] + ["B", 200]]),
        "point 'S2' has 1 row": _csv(tmp_path / "pt1.csv", f"{q},point",
                                     [r + ["S1"] for r in rows[:9]] + [rows[9] + ["S2"]]),
        "plane 'F2' has 2 rows": _csv(tmp_path / "pl2.csv", f"{q},plane",
                                      [r + ["F1"] for r in rows[:8]]
                                      + [r + ["F2"] for r in rows[8:]]),
        "pair '2' has 1 row": _csv(tmp_path / "pr.csv", f"{q},pair,distance",
                                   [r + [i // 2, 300] for i, r in enumerate(rows[:5])]),
        "5 joint columns": _csv(tmp_path / "q5.csv", "q1,q2,q3,q4,q5,point",
                                [r[:5] + ["S1"] for r in rows]),
        "columns of 2 measurement kinds": _csv(tmp_path / "mix.csv", f"{q},x,y,z,point",
                                               [r + [1, 2, 3, "S1"] for r in rows]),
        "without a distance column": _csv(tmp_path / "nod.csv", f"{q},pivot",
                                          [r + ["A"] for r in rows]),
    }
    for expected, path in cases.items():
        code = main(["calibrate", "irb120", str(files / "bb.csv"), path, "--quiet"])
        err = capsys.readouterr().err
        assert code == 2 and expected in err and err.count("\n") == 1, (expected, err)
    # a distance column in metres for a millimetre model: a named warning, exit 2 --strict
    m = kinecal.load_model("irb120")
    bb = read_gauge(files / "bb.csv", m)
    import dataclasses

    write_gauge(tmp_path / "metres.csv", dataclasses.replace(bb, distance=bb.distance / 1e3), m)
    code = main(["calibrate", "irb120", str(tmp_path / "metres.csv"), str(files / "pt.csv"),
                 "--strict"])
    err = capsys.readouterr().err
    assert code == 2 and "metres in a millimetre model" in err and "[scale-mismatch]" in err
    # another robot's file among the files: named (initial-error), exit 2 under --strict
    assert main(["simulate", "puma560", "--kind", "ballbar", "--poses", "16", "--seed", "3",
                 "--out", str(tmp_path / "puma.csv"), "--quiet"]) == 0
    code = main(["calibrate", "irb120", str(files / "bb.csv"), str(tmp_path / "puma.csv"),
                 str(files / "pt.csv"), "--strict"])
    err = capsys.readouterr().err
    assert code == 2 and "puma.csv" in err and (
        "[initial-error]" in err or "[scale-mismatch]" in err or "[joint-limits]" in err), err
    # --sigma naming no file, and options of the one-tracker-file path
    code = main(["calibrate", "irb120", str(files / "bb.csv"), str(files / "pt.csv"),
                 "--sigma", "nope.csv=0.1"])
    assert code == 2 and "--sigma" in capsys.readouterr().err
    code = main(["calibrate", "irb120", str(files / "bb.csv"), "--error-model", "compliance"])
    assert code == 2 and "--error-model" in capsys.readouterr().err


def test_a_batch_job_takes_several_files_of_any_kinds(files, capsys):
    jobs = files / "jobs.yaml"
    jobs.write_text("jobs:\n  - {name: mix, model: irb120, data: [bb.csv, pt.csv], "
                    "sigma: [0.002, null]}\n  - {name: bad, model: irb120, data: [bb.csv], "
                    "sigma: [0.1, 0.2]}\n", encoding="utf-8")
    assert main(["batch", str(jobs), "--out", str(files / "out"), "--workers", "1",
                 "--quiet"]) == 2  # two sigmas for one file: refused before any job
    assert "2 values for 1 data files" in capsys.readouterr().err
    jobs.write_text("jobs:\n  - {name: mix, model: irb120, data: [bb.csv, pt.csv], "
                    "sigma: [0.002, null]}\n", encoding="utf-8")
    assert main(["batch", str(jobs), "--out", str(files / "out"), "--workers", "1",
                 "--quiet"]) == 0, capsys.readouterr().err
    r = json.loads((files / "out" / "mix.json").read_text())
    assert [k["kind"] for k in r["kinds"]] == ["ballbar", "point"]
    assert r["kinds"][0]["sigma_source"] == "stated" and r["job"]["data"][0].endswith("bb.csv")
