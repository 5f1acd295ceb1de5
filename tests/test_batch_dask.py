"""kinecal.batch on a Dask LocalCluster (2 worker processes, loopback): the same results as
the process pool, and a killed worker does not lose a job."""

from __future__ import annotations

import json
import os
import signal

import pytest

from kinecal.batch import parse_jobs, run_batch

distributed = pytest.importorskip("distributed")  # the optional extra kinecal[dask]

from kinecal.batch import dask_executor  # noqa: E402

#: 20 cheap jobs: 2 methods x 2 noise levels x 5 seeds, 15 poses
STUDY = {"model": "irb120", "methods": ["lm", "householder"], "seeds": 5,
         "noise": [0.01, 0.05], "poses": [15], "validation_poses": 10}


@pytest.fixture(scope="module")
def dask_ex():
    with dask_executor(workers=2) as ex:
        yield ex


def _numbers(path):
    """A result JSON without its timings, as text (NaN compares equal to NaN here)."""
    res = json.loads(path.read_text(encoding="utf-8"))
    return json.dumps({k: v for k, v in res.items() if k not in ("seconds", "batch")},
                      sort_keys=True)


def test_local_cluster_is_two_loopback_worker_processes(dask_ex):
    info = dask_ex._client.scheduler_info()
    assert len(info["workers"]) == 2
    assert all(addr.startswith("tcp://127.0.0.1:") for addr in info["workers"])
    assert all(w["nthreads"] == 1 for w in info["workers"].values())
    pids = dask_ex._client.run(os.getpid)
    assert len(set(pids.values())) == 2 and os.getpid() not in pids.values()


def test_study_on_dask_equals_study_on_process_pool(dask_ex, tmp_path):
    jobs = parse_jobs({"study": STUDY})
    assert len(jobs) == 20
    on_dask = run_batch(jobs, tmp_path / "dask", executor=dask_ex)
    on_pool = run_batch(jobs, tmp_path / "pool", workers=2)
    assert on_dask.counts == on_pool.counts == {"done": 20}
    for job in jobs:
        assert _numbers(tmp_path / "dask" / f"{job.name}.json") == \
            _numbers(tmp_path / "pool" / f"{job.name}.json")
    # same seed, same true arm for both methods; other seeds, other arms
    truths = {json.dumps(json.loads((tmp_path / "dask" / f"{j.name}.json").read_text())
                         ["truth"]) for j in jobs}
    assert len(truths) == 5
    for a, b in zip(on_dask.records, on_pool.records, strict=True):
        assert (a.name, a.calibration_mean, a.validation_mean) == \
            (b.name, b.calibration_mean, b.validation_mean)


def test_killed_dask_worker_loses_no_job(dask_ex, tmp_path):
    jobs = parse_jobs({"study": STUDY})
    client = dask_ex._client
    victims = list(client.run(os.getpid).values())
    killed = []

    def kill_one_worker(rec):
        if not killed and rec.status == "done":
            killed.append(victims[0])
            os.kill(victims[0], signal.SIGKILL)

    out = run_batch(jobs, tmp_path, executor=dask_ex, on_result=kill_one_worker)
    assert killed
    assert out.ok and out.counts == {"done": 20}
    assert len(list(tmp_path.glob("irb120-*.json"))) == 20
    # the nanny restarted the worker: the cluster is whole again
    client.wait_for_workers(2, timeout=30)
    assert victims[0] not in client.run(os.getpid).values()


def test_cli_connects_to_a_scheduler_address(dask_ex, tmp_path, capsys):
    from kinecal.cli import main

    address = dask_ex._client.scheduler.address
    assert address.startswith("tcp://127.0.0.1:")
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text("study: {model: irb120, seeds: 3, poses: [15], noise: [0.01]}\n",
                    encoding="utf-8")
    code = main(["batch", str(jobs), "--executor", "dask", "--scheduler", address,
                 "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    assert "3 jobs: 3 done" in capsys.readouterr().err
    assert len(list((tmp_path / "out").glob("irb120-lm-*.json"))) == 3


def test_cli_unreachable_scheduler_is_an_input_error(tmp_path, capsys, monkeypatch):
    from kinecal.batch import executors
    from kinecal.cli import main

    monkeypatch.setattr(executors, "CONNECT_TIMEOUT", "1s")

    jobs = tmp_path / "jobs.yaml"
    jobs.write_text("study: {model: irb120, seeds: 1, poses: [15]}\n", encoding="utf-8")
    code = main(["batch", str(jobs), "--executor", "dask", "--scheduler", "tcp://127.0.0.1:9",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "option --scheduler" in err and err.count("\n") == 1
