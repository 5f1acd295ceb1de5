"""Several measurement files of any kinds on the command line (issue 25): the walkthrough
of docs/measurement-kinds.md run as written (simulate two kinds of one hidden arm, plan,
calibrate, validate, the Python API), files read back, a batch job of several files, and
the bad inputs of the issue: exit 2 with one line, or a named warning."""

import contextlib
import io
import json
import os
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

import kinecal
from kinecal.cli import main
from kinecal.io.kinds import read_gauge, read_kind, write_gauge

DOC = Path(__file__).resolve().parents[2] / "docs" / "measurement-kinds.md"


def _run_block(block: str, printed: list[str]) -> None:
    """One shell block of the walkthrough, in this process: ``kinecal ...`` lines with the
    argv the shell would give them, ``python -c CODE`` and a ``python - <<'EOF'`` script
    by exec (their stdout collected); anything else is a failure (keep the page simple)."""
    if block.startswith("python - <<'EOF'\n"):
        body = block.split("\n", 1)[1].rsplit("EOF", 1)[0]
        lines = [("python", body)]
    else:
        lines = [(shlex.split(line)[0], line) for line in block.strip().splitlines()]
    for prog, line in lines:
        if prog == "kinecal":
            assert main(shlex.split(line)[1:]) == 0, line
            continue
        assert prog == "python", line
        code = line if "\n" in line else shlex.split(line)[2]
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            exec(compile(code, "<walkthrough>", "exec"), {"__name__": "__main__"})
        printed.append(out.getvalue())


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The walkthrough of docs/measurement-kinds.md, run as written in an empty folder
    (`_run_block`). Returns the folder; what it printed is in ``walkthrough.txt``."""
    d = tmp_path_factory.mktemp("walkthrough")
    section = DOC.read_text(encoding="utf-8").split("## Walkthrough", 1)[1]
    blocks = re.findall(r"^```sh\n(.*?)^```", section, flags=re.S | re.M)
    assert len(blocks) >= 6
    printed: list[str] = []
    cwd = os.getcwd()
    os.chdir(d)
    try:
        for block in blocks:
            _run_block(block, printed)
    finally:
        os.chdir(cwd)
    (d / "walkthrough.txt").write_text("".join(printed), encoding="utf-8")
    return d


def test_the_walkthrough_runs_as_written_and_calibrates_the_hidden_arm(files):
    r = json.loads((files / "result.json").read_text())
    kinds = {k["kind"]: k for k in r["kinds"]}
    assert set(kinds) == {"ballbar", "point"} and r["not_seen"] == ["translation z",
                                                                     "rotation z"]
    assert kinds["ballbar"]["sigma_source"] == "stated"
    assert [u["pivot"] for u in kinds["ballbar"]["unknowns"]] == ["P1", "P2"]
    assert kinds["ballbar"]["after"]["rms"] < 0.003 < 1 < kinds["ballbar"]["before"]["rms"]
    v = r["validation"]
    assert v["after"]["rms"] < 0.01 < 1 < v["before"]["rms"]  # the held-out ballbar
    assert kinecal.load_model(str(files / "calibrated.yaml")).name.endswith("calibrated")
    out = (files / "walkthrough.txt").read_text().splitlines()
    sigma = json.loads(out[1].replace("'", '"'))  # the estimated noise of each file
    assert 0.001 < sigma[0] < 0.003 and 0.007 < sigma[1] < 0.013
    before, after = map(float, re.findall(r"([0-9.]+) mm", out[2]))
    assert after < 0.03 * before


def _csv(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(str(c) for c in r) for r in rows)
                    + "\n", encoding="utf-8")
    return str(path)


def test_simulated_files_read_back_with_their_kind(files):
    m = kinecal.load_model("irb120")
    bb, pt = read_kind(files / "ballbar.csv", m), read_kind(files / "sockets.csv", m)
    assert (bb.kind, pt.kind) == ("ballbar", "point")
    assert bb.group_names == ("P1", "P2") and len(bb) == 50
    np.testing.assert_allclose(bb.distance, 150.0, atol=0.01)
    write_gauge(files / "copy.csv", pt, m)
    back = read_gauge(files / "copy.csv", m)
    np.testing.assert_array_equal(back.q, pt.q)
    assert back.group_names == pt.group_names and np.array_equal(back.group, pt.group)


def test_identifiability_plans_a_mix(files, capsys):
    code = main(["identifiability", "irb120", "--data", str(files / "ballbar.csv"), "--data",
                 str(files / "sockets.csv"), "--json"])
    assert code == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["not_seen"] == ["translation z", "rotation z"]
    assert {"theta1", "d1"} <= set(rep["unidentifiable"])
    assert [k["unknowns"] for k in rep["kinds"]] == [6, 12]
    capsys.readouterr()
    code = main(["identifiability", "irb120", "--data", str(files / "sockets.csv"), "--json"])
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
        code = main(["calibrate", "irb120", str(files / "ballbar.csv"), path, "--quiet"])
        err = capsys.readouterr().err
        assert code == 2 and expected in err and err.count("\n") == 1, (expected, err)
    # a distance column in metres for a millimetre model: a named warning, exit 2 --strict
    m = kinecal.load_model("irb120")
    bb = read_gauge(files / "ballbar.csv", m)
    import dataclasses

    write_gauge(tmp_path / "metres.csv", dataclasses.replace(bb, distance=bb.distance / 1e3), m)
    code = main(["calibrate", "irb120", str(tmp_path / "metres.csv"), str(files / "sockets.csv"),
                 "--strict"])
    err = capsys.readouterr().err
    assert code == 2 and "metres in a millimetre model" in err and "[scale-mismatch]" in err
    # another robot's file among the files: named (initial-error), exit 2 under --strict
    assert main(["simulate", "puma560", "--kind", "ballbar", "--poses", "16", "--seed", "3",
                 "--out", str(tmp_path / "puma.csv"), "--quiet"]) == 0
    code = main(["calibrate", "irb120", str(files / "ballbar.csv"), str(tmp_path / "puma.csv"),
                 str(files / "sockets.csv"), "--strict"])
    err = capsys.readouterr().err
    assert code == 2 and "puma.csv" in err and (
        "[initial-error]" in err or "[scale-mismatch]" in err or "[joint-limits]" in err), err
    # --sigma naming no file, and options of the one-tracker-file path
    code = main(["calibrate", "irb120", str(files / "ballbar.csv"), str(files / "sockets.csv"),
                 "--sigma", "nope.csv=0.1"])
    assert code == 2 and "--sigma" in capsys.readouterr().err
    code = main(["calibrate", "irb120", str(files / "ballbar.csv"), "--error-model", "compliance"])
    assert code == 2 and "--error-model" in capsys.readouterr().err


def test_a_batch_job_takes_several_files_of_any_kinds(files):
    from kinecal.batch.jobs import parse_jobs
    from kinecal.batch.work import run_job
    from kinecal.errors import InputError

    doc = {"jobs": [{"name": "mix", "model": "irb120", "data": ["ballbar.csv", "sockets.csv"],
                     "sigma": [0.002, None]}]}
    with pytest.raises(InputError, match="2 values for 1 data files"):
        parse_jobs({"jobs": [{**doc["jobs"][0], "data": ["ballbar.csv"]}]}, files)
    out = run_job(parse_jobs(doc, files)[0])
    assert out["status"] == "done", out["error"]
    r = out["result"]
    assert [k["kind"] for k in r["kinds"]] == ["ballbar", "point"]
    assert [k["sigma_source"] for k in r["kinds"]] == ["stated", "estimated"]
    assert r["job"]["data"][0].endswith("ballbar.csv")
