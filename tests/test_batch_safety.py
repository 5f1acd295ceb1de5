"""Batch runs: outputs never land on inputs, resume follows the inputs' content, and a
killed coordinator leaves no worker behind (SIGTERM also writes the summary)."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import psutil
import pytest

from kinecal.batch import parse_jobs, run_batch
from kinecal.calibration.serial.simulate import simulate
from kinecal.errors import InputError
from kinecal.io.measurements import write_measurements
from kinecal.io.models import load_model

ROBOTS = Path(__file__).resolve().parents[1] / "src" / "kinecal" / "robots"
SRC = str(Path(__file__).resolve().parents[1] / "src")


def _arm(tmp_path: Path, name: str, seed: int, n: int = 20) -> None:
    model = load_model("irb120")
    write_measurements(tmp_path / name, simulate(model, n, noise=0.01, rng=seed).data, model)


def _statuses(out) -> list[str]:
    return [r.status for r in out.records]


def test_resume_recomputes_jobs_whose_inputs_changed(tmp_path):
    _arm(tmp_path, "a.csv", 0)
    _arm(tmp_path, "b.csv", 1)
    (tmp_path / "arm.yaml").write_text((ROBOTS / "irb120.yaml").read_text(encoding="utf-8"),
                                       encoding="utf-8")
    doc = {"jobs": [{"name": "a", "model": "irb120", "data": "a.csv"},
                    {"name": "b", "model": "irb120", "data": "b.csv"},
                    {"name": "c", "model": "arm.yaml", "poses": 25}]}
    jobs = parse_jobs(doc, tmp_path)
    with ThreadPoolExecutor(2) as ex:
        assert _statuses(run_batch(jobs, tmp_path / "out", executor=ex)) == ["done"] * 3
        first = json.loads((tmp_path / "out" / "a.json").read_text())
        assert len(first["batch"]["input_hash"]) == 64
        assert _statuses(run_batch(jobs, tmp_path / "out", executor=ex)) == ["resumed"] * 3
        _arm(tmp_path, "a.csv", 5)  # new measurements under the same name: same job spec
        model = (tmp_path / "arm.yaml").read_text(encoding="utf-8")
        (tmp_path / "arm.yaml").write_text(model + "# edited\n", encoding="utf-8")
        assert _statuses(run_batch(jobs, tmp_path / "out", executor=ex)) == [
            "done", "resumed", "done"]
        second = json.loads((tmp_path / "out" / "a.json").read_text())
        assert second["batch"]["input_hash"] != first["batch"]["input_hash"]
        assert second["calibration"]["before"] != first["calibration"]["before"]
        # a result from before input hashes existed is computed again, once
        del second["batch"]["input_hash"]
        (tmp_path / "out" / "a.json").write_text(json.dumps(second), encoding="utf-8")
        assert _statuses(run_batch(jobs, tmp_path / "out", executor=ex)) == [
            "done", "resumed", "resumed"]


def test_outputs_on_inputs_are_refused_before_any_job(tmp_path):
    _arm(tmp_path, "summary.csv", 0)
    _arm(tmp_path, "x.csv", 1)
    os.link(tmp_path / "x.csv", tmp_path / "hard.json")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    cases = [
        ([{"name": "a", "model": "irb120", "data": "summary.csv"}], "the batch's summary.csv"),
        ([{"name": "hard", "model": "irb120", "data": "x.csv"}], "the data file of job hard"),
        ([{"name": "b", "model": "irb120", "data": "x.csv", "validate": "summary.csv"}],
         "the validate file of job b"),
    ]
    for doc, words in cases:
        jobs = parse_jobs({"jobs": doc}, tmp_path)
        with pytest.raises(InputError, match=words):
            run_batch(jobs, tmp_path, executor=ThreadPoolExecutor(1))
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


SLOW_JOBS = """jobs:
  - {name: slow1, model: irb120, poses: 30, method: pso, maxiter: 1000000}
  - {name: slow2, model: irb120, poses: 30, method: pso, maxiter: 1000000}
  - {name: quick, model: irb120, poses: 30}
"""


def _workers(coordinator: psutil.Process) -> list[psutil.Process]:
    """The pool's worker processes: children of the coordinator's fork server that have run
    their initializer (`kinecal.batch.executors.watch_parent` starts a thread). Read from
    the process tree alone: nothing here depends on how busy the machine is."""
    out = []
    for server in coordinator.children():
        with contextlib.suppress(psutil.Error):
            if "multiprocessing.forkserver" in " ".join(server.cmdline()):
                out += [w for w in server.children() if w.num_threads() >= 2]
    return out


def _start_batch(tmp_path: Path) -> tuple[subprocess.Popen, list[psutil.Process]]:
    """A batch of two long jobs on two workers, started in its own session; returns it
    and its process tree once both workers are up."""
    (tmp_path / "jobs.yaml").write_text(SLOW_JOBS, encoding="utf-8")
    env = dict(os.environ, PYTHONPATH=SRC)
    proc = subprocess.Popen(
        [sys.executable, "-c", "from kinecal.cli import main; main()", "batch", "jobs.yaml",
         "--out", "out", "--workers", "2", "--quiet"],
        cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        start_new_session=True)
    coordinator = psutil.Process(proc.pid)
    deadline = time.monotonic() + 300  # a bound on a stuck start, not a timing
    while time.monotonic() < deadline and proc.poll() is None:
        with contextlib.suppress(psutil.Error):
            if len(_workers(coordinator)) >= 2:
                return proc, coordinator.children(recursive=True)
        time.sleep(0.2)
    proc.kill()
    raise AssertionError("the batch workers did not start")


def _survivors(kids: list[psutil.Process], wait: float = 10.0) -> list[psutil.Process]:
    deadline = time.monotonic() + wait
    while True:
        alive = [k for k in kids if k.is_running() and k.status() != psutil.STATUS_ZOMBIE]
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.1)


@pytest.mark.parametrize("sig", ["SIGKILL", "SIGTERM"])
def test_killed_coordinator_leaves_no_worker(tmp_path, sig):
    proc, kids = _start_batch(tmp_path)
    try:
        os.kill(proc.pid, getattr(signal, sig))
        proc.wait(30)
        left = _survivors(kids)
        assert left == [], [(k.pid, " ".join(k.cmdline())[:80]) for k in left]
        err = proc.stderr.read().decode()  # once every process holding it has ended
        assert "leaked" not in err and "resource_tracker" not in err, err
        if sig == "SIGTERM":  # like Ctrl-C: the summary, the resume hint, status 143
            assert proc.returncode == 143
            assert err.endswith("kinecal: terminated\n") and "to resume" in err
            with open(tmp_path / "out" / "summary.csv", newline="", encoding="utf-8") as fh:
                rows = list(csv.DictReader(fh))
            assert [r["name"] for r in rows] == ["slow1", "slow2", "quick"]
            assert {r["status"] for r in rows[:2]} == {"not run"}
        assert not [p for p in (tmp_path / "out").iterdir() if p.name.endswith(".tmp")] \
            if (tmp_path / "out").exists() else True
    finally:
        for k in kids:
            if k.is_running():
                k.kill()
        if proc.poll() is None:
            proc.kill()
