"""kinecal.batch.run_batch on a process pool: outputs, failures, resume, dead workers."""

from __future__ import annotations

import csv
import json
import os
import signal

import numpy as np
import pytest

from kinecal.batch import load_results, local_executor, parse_jobs, run_batch, run_job
from kinecal.batch.records import SUMMARY_COLUMNS
from kinecal.calibration.serial.simulate import simulate
from kinecal.io.measurements import write_measurements
from kinecal.io.models import load_model

#: 20 cheap jobs: 2 methods x 2 noise levels x 5 seeds, 15 poses
STUDY = {"model": "irb120", "methods": ["lm", "householder"], "seeds": 5,
         "noise": [0.01, 0.05], "poses": [15], "validation_poses": 10}


def _strip(result):
    """A result without its timings (the only numbers allowed to differ between runs)."""
    return {k: v for k, v in result.items() if k not in ("seconds", "batch")}


def _summary(path):
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_fleet_of_measured_arms_with_one_missing_file(tmp_path):
    model = load_model("irb120")
    for k in range(2):
        sim = simulate(model, 20, noise=0.005, rng=k)
        val = simulate(model, 15, errors=sim.true_params - model.nominal, noise=0.005,
                       rng=100 + k)
        write_measurements(tmp_path / f"arm-{k}.csv", sim.data, model)
        write_measurements(tmp_path / f"arm-{k}-val.csv", val.data, model)
    doc = {"jobs": [{"name": f"arm-{k}", "model": "irb120", "data": f"arm-{k}.csv",
                     "validate": f"arm-{k}-val.csv"} for k in range(2)]}
    doc["jobs"].insert(1, {"name": "arm-x", "model": "irb120", "data": "arm-x.csv"})
    jobs = parse_jobs(doc, tmp_path)
    out = run_batch(jobs, tmp_path / "out", workers=2)
    assert [r.status for r in out.records] == ["done", "failed", "done"]
    assert not out.ok
    assert "arm-x.csv" in out.records[1].error and out.records[1].kind == "input"
    assert not (tmp_path / "out" / "arm-x.json").exists()
    rows = _summary(out.summary_path)
    assert tuple(rows[0]) == SUMMARY_COLUMNS
    assert [r["name"] for r in rows] == ["arm-0", "arm-x", "arm-1"]
    for k, row in zip((0, 2), (rows[0], rows[2]), strict=True):
        res = json.loads((tmp_path / "out" / f"arm-{k // 2}.json").read_text())
        assert res["validation"]["n"] == 15 and res["calibration"]["n"] == 20
        # the summary repeats the JSON's numbers; calibrated arms reach the noise floor
        assert float(row["validation_mean"]) == res["validation"]["after"]["mean"]
        assert float(row["calibration_mean"]) == res["calibration"]["after"]["mean"]
        assert res["validation"]["after"]["mean"] < 0.05 < res["validation"]["before"]["mean"]
        assert row["status"] == "done" and row["noise"] == "" and row["poses"] == "20"
    assert rows[1]["status"] == "failed" and "not found" in rows[1]["error"]


def test_pool_results_equal_in_process_results(tmp_path):
    jobs = parse_jobs({"study": {**STUDY, "seeds": [0, 1]}})
    out = run_batch(jobs, tmp_path, workers=2)
    assert out.ok and out.counts == {"done": 8}
    for job in jobs:
        on_disk = json.loads((tmp_path / f"{job.name}.json").read_text())
        here = json.loads(json.dumps(run_job(job)["result"]))
        assert _strip(on_disk) == _strip(here)


def test_interrupted_run_resumes_without_recomputing(tmp_path):
    jobs = parse_jobs({"study": STUDY})
    assert len(jobs) == 20
    seen = []

    def stop_after_six(rec):
        seen.append(rec.status)
        if len(seen) == 6:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch(jobs, tmp_path, workers=2, on_result=stop_after_six)
    finished = sorted(p.name for p in tmp_path.glob("irb120-*.json"))
    assert len(finished) == 6
    rows = _summary(tmp_path / "summary.csv")  # written even when interrupted
    assert sum(r["status"] == "done" for r in rows) == 6
    assert sum(r["status"] == "not run" for r in rows) == 14
    stamps = {n: (os.stat(tmp_path / n).st_ino, os.stat(tmp_path / n).st_mtime_ns)
              for n in finished}

    # a rerun computes only the 14 others and leaves the 6 files untouched
    out = run_batch(jobs, tmp_path, workers=2)
    assert out.counts == {"resumed": 6, "done": 14}
    assert sorted(r.name + ".json" for r in out.records if r.status == "resumed") == finished
    assert stamps == {n: (os.stat(tmp_path / n).st_ino, os.stat(tmp_path / n).st_mtime_ns)
                      for n in finished}
    assert len(load_results(tmp_path, out.records)) == 20
    # resumed records carry the stored numbers, not blanks
    assert all(np.isfinite(r.validation_mean) for r in out.records)

    # a changed job is not "finished": only it is recomputed
    changed = [j.model_copy(update={"loss": "huber"}) if j.name == jobs[0].name else j
               for j in jobs]
    again = run_batch(changed, tmp_path, workers=2)
    assert again.counts == {"resumed": 19, "done": 1}
    assert again.records[0].status == "done"


def test_killed_worker_gets_its_job_retried(tmp_path):
    jobs = parse_jobs({"study": STUDY})
    pools = []

    def factory():
        pools.append(local_executor(2))
        return pools[-1]

    statuses, killed = [], []

    def kill_one_worker(rec):
        statuses.append(rec.status)
        if not killed and statuses.count("done") == 3:
            killed.append(next(iter(pools[0]._processes)))  # the worker pids
            os.kill(killed[0], signal.SIGKILL)

    out = run_batch(jobs, tmp_path, executor=factory, on_result=kill_one_worker, window=4)
    # the broken pool was replaced and every job still has its result
    assert len(pools) == 2
    assert out.ok and out.counts == {"done": 20}
    assert max(r.attempts for r in out.records) == 2
    assert len(list(tmp_path.glob("irb120-*.json"))) == 20
    ref = parse_jobs({"study": {**STUDY, "methods": ["householder"], "seeds": [4]}})[0]
    on_disk = json.loads((tmp_path / f"{ref.name}.json").read_text())
    assert _strip(on_disk) == _strip(json.loads(json.dumps(run_job(ref)["result"])))


def test_job_that_always_kills_its_worker_is_given_up(tmp_path, monkeypatch):
    # a job function the pool's workers can import: a module on the (inherited) sys.path
    (tmp_path / "kinecal_batch_crash.py").write_text(
        "import os\n\n\ndef die(job):\n    os._exit(3)\n", encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    from kinecal_batch_crash import die

    jobs = parse_jobs({"jobs": [{"name": "a", "model": "irb120", "poses": 12},
                                {"name": "b", "model": "irb120", "poses": 12}]})
    out = run_batch(jobs, tmp_path / "out", workers=1, window=1, job_function=die,
                    max_attempts=2)
    rec = out.records[0]
    assert rec.status == "failed" and rec.attempts == 2 and "worker died" in rec.error
    assert [r.status for r in out.records] == ["failed", "failed"]
    assert not list((tmp_path / "out").glob("*.json"))


def test_any_executor_thread_pool_instance_and_factory(tmp_path):
    from concurrent.futures import ThreadPoolExecutor

    jobs = parse_jobs({"study": {**STUDY, "methods": ["householder"], "seeds": [0, 1],
                                 "noise": [0.01]}})
    with ThreadPoolExecutor(2) as ex:
        given = run_batch(jobs, tmp_path / "given", executor=ex)
    made = run_batch(jobs, tmp_path / "made", executor=lambda: ThreadPoolExecutor(2))
    assert given.counts == made.counts == {"done": 2}
    for job in jobs:
        assert _strip(json.loads((tmp_path / "given" / f"{job.name}.json").read_text())) == \
            _strip(json.loads((tmp_path / "made" / f"{job.name}.json").read_text()))
