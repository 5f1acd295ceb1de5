"""``kinecal batch`` command line."""

from __future__ import annotations

import csv
import json

import pytest

from kinecal.cli import main

JOBS = """
jobs:
  - {name: broken, model: irb120, data: missing.csv}
study: {model: irb120, name: cov, methods: [lm], seeds: 6, noise: [0.02], poses: [20],
        validation_poses: 10, errors: identifiable}
"""


def test_batch_command_runs_resumes_and_reports(tmp_path, capsys):
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text(JOBS, encoding="utf-8")
    out = tmp_path / "out"
    code = main(["batch", str(jobs), "--out", str(out), "--workers", "2"])
    cap = capsys.readouterr()
    # the missing file is a user mistake: exit 2, the other jobs still done
    assert code == 2
    assert "7 jobs: 6 done, 1 failed" in cap.err
    assert "missing.csv: file not found" in cap.out
    with open(out / "summary.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["status"] for r in rows] == ["failed"] + ["done"] * 6
    assert [r["seed"] for r in rows[1:]] == [str(s) for s in range(6)]
    res = json.loads((out / "cov-lm-n0.02-p20-s3.json").read_text())
    assert res["method"] == "lm" and res["seed"] == 3 and res["job"]["noise"] == 0.02
    with open(out / "study.csv", newline="", encoding="utf-8") as fh:
        study = list(csv.DictReader(fh))
    assert len(study) == 1 and study[0]["runs"] == "6"
    vals = sorted(float(r["validation_mean"]) for r in rows[1:])
    assert float(study[0]["validation_median"]) == pytest.approx((vals[2] + vals[3]) / 2,
                                                                 rel=1e-3)
    with open(out / "coverage.csv", newline="", encoding="utf-8") as fh:
        cov = list(csv.DictReader(fh))
    assert cov[0]["runs"] == "6" and 0.0 <= float(cov[0]["coverage"]) <= 1.0
    assert "coverage of the 95 % intervals" in cap.out

    # rerun: finished jobs are resumed, the failed one is tried again (and fails again)
    jobs.write_text(JOBS.replace("  - {name: broken, model: irb120, data: missing.csv}\n",
                                 "").replace("jobs:\n", ""), encoding="utf-8")
    assert main(["batch", str(jobs), "--out", str(out), "--quiet"]) == 0
    assert "6 resumed" in capsys.readouterr().err


@pytest.mark.parametrize("args, words", [
    (["--executor", "spark"], "option --executor"),
    (["--scheduler", "tcp://127.0.0.1:1"], "option --scheduler"),
    (["--workers", "0"], "option --workers"),
])
def test_batch_bad_options_exit_2(tmp_path, capsys, args, words):
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text(JOBS, encoding="utf-8")
    assert main(["batch", str(jobs), "--out", str(tmp_path / "o"), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err
    assert not (tmp_path / "o").exists()


def test_batch_bad_jobs_file_exit_2(tmp_path, capsys):
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text("study: {model: irb120, poses: [10], methods: [simplex]}\n", encoding="utf-8")
    assert main(["batch", str(jobs), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "jobs.yaml" in err and "unknown method 'simplex'" in err


def test_batch_interrupt_exits_130_and_says_how_to_resume(tmp_path, capsys, monkeypatch):
    import kinecal.batch

    def interrupted(jobs, out, on_result=None, **kwargs):
        on_result(kinecal.batch.JobRecord("x", "lm", 0, 0.0, 10, status="done"))
        raise KeyboardInterrupt

    monkeypatch.setattr(kinecal.batch, "run_batch", interrupted)
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text(JOBS, encoding="utf-8")
    assert main(["batch", str(jobs), "--out", str(tmp_path / "o"), "--quiet"]) == 130
    err = capsys.readouterr().err
    assert "1 of 7 jobs have results" in err and "resume" in err
    assert err.rstrip().endswith("kinecal: interrupted")
