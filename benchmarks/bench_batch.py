"""Batch runs: throughput with 1 and 2 workers (process pool, Dask), Monte Carlo coverage.

Run ``python benchmarks/bench_batch.py [--quick]``. BLAS pinned to one thread per process.

Throughput: the same study of simulated ``lm`` calibrations (irb120, 30 poses, 50
validation poses) is run by a plain serial loop of `kinecal.batch.run_job` in this
process (the peer), by `run_batch` on a process pool of 1 and 2 workers and on a Dask
`LocalCluster` of 1 and 2 single-threaded worker processes. Executors are started and
warmed up (one job per worker) before timing, so the numbers are steady-state jobs/s
including result files and summary. The ratios say what a second worker buys on this
machine (2 cores, shared) and what the pool and Dask cost over a serial loop; each is the
best of 3 interleaved rounds (the machine is shared with other jobs). The JSON
numbers of the pool and Dask runs are compared (they must be identical).

Coverage (the calibration issue's "standard errors whose 95 % intervals cover the truth in
90-99 % of 200 Monte Carlo runs"): 200 seeds per noise level of ``errors: identifiable``
jobs (true errors uniform within the irb120 tolerances on the parameters identifiable from
the poses), ``lm``; fraction of (run, free parameter) pairs with the truth inside
``identified +- 1.96 std``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from kinecal.batch import (  # noqa: E402
    coverage_table,
    format_table,
    load_results,
    local_executor,
    parameter_coverage,
    parse_jobs,
    run_batch,
    run_job,
    study_table,
)


def _study(n: int, prefix: str) -> list:
    return parse_jobs({"study": {"model": "irb120", "name": prefix, "methods": ["lm"],
                                 "seeds": n, "noise": [0.01], "poses": [30],
                                 "validation_poses": 50}})


def _warm(executor, workers: int) -> None:
    warm = _study(workers, "warm")
    for fut in [executor.submit(run_job, job) for job in warm]:
        fut.result()


def _timed(jobs, out: Path, executor, window: int | None) -> float:
    t0 = time.perf_counter()
    res = run_batch(jobs, out, executor=executor, window=window)
    elapsed = time.perf_counter() - t0
    assert res.counts == {"done": len(jobs)}, res.counts
    return len(jobs) / elapsed


def _numbers(path: Path) -> str:
    res = json.loads(path.read_text(encoding="utf-8"))
    return json.dumps({k: v for k, v in res.items() if k not in ("seconds", "batch")},
                      sort_keys=True)


def throughput(n_jobs: int, tmp: Path, repeat: int) -> list[dict]:
    """jobs/s of the serial peer, the pool and Dask with 1 and 2 workers (best of `repeat`
    interleaved rounds: the machine is shared)."""
    import contextlib

    jobs = _study(n_jobs, "tp")
    run_job(jobs[0])  # warm-up of the peer (imports)
    best: dict[tuple[str, int], float] = {}
    with contextlib.ExitStack() as stack:
        executors = {}
        for workers in (1, 2):
            executors["process pool", workers] = (
                stack.enter_context(local_executor(workers)), 2 * workers)
        try:
            from kinecal.batch import dask_executor

            for workers in (1, 2):
                executors["dask LocalCluster", workers] = (
                    stack.enter_context(dask_executor(workers=workers)), None)
        except Exception as exc:  # the optional extra may be missing: report and go on
            print(f"dask skipped: {type(exc).__name__}: {exc}")
        for (_, workers), (ex, _) in executors.items():
            _warm(ex, workers)
        for r in range(repeat):
            t0 = time.perf_counter()
            for job in jobs:
                run_job(job)
            rate = n_jobs / (time.perf_counter() - t0)
            best["serial loop (peer)", 1] = max(best.get(("serial loop (peer)", 1), 0), rate)
            for key, (ex, window) in executors.items():
                out = tmp / f"{key[0].split()[0]}{key[1]}-{r}"
                best[key] = max(best.get(key, 0.0), _timed(jobs, out, ex, window))
    serial = best["serial loop (peer)", 1]
    rows = []
    for (name, workers), rate in best.items():
        rows.append({"executor": name, "workers": workers, "jobs/s": rate,
                     "vs 1 worker": rate / best[name, 1], "vs serial": rate / serial})
    if (tmp / "dask2-0").exists():
        same = sum(_numbers(tmp / "process2-0" / f"{j.name}.json")
                   == _numbers(tmp / "dask2-0" / f"{j.name}.json") for j in jobs)
        print(f"pool vs Dask (2 workers): {same} of {len(jobs)} result files with identical "
              "numbers")
    return rows


def coverage(runs: int, noise: list[float], tmp: Path, workers: int,
             ) -> tuple[list, list, list, float]:
    """Monte Carlo coverage of the reported standard errors (errors: identifiable, lm)."""
    jobs = parse_jobs({"study": {"model": "irb120", "name": "cov", "methods": ["lm"],
                                 "seeds": runs, "noise": noise, "poses": [30],
                                 "validation_poses": 50, "errors": "identifiable"}})
    t0 = time.perf_counter()
    res = run_batch(jobs, tmp / "coverage", workers=workers)
    elapsed = time.perf_counter() - t0
    results = load_results(tmp / "coverage", res.records)
    return (coverage_table(results), parameter_coverage(results), study_table(res.records),
            elapsed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer jobs and runs")
    args = parser.parse_args()
    n_jobs, runs, repeat = (16, 40, 1) if args.quick else (60, 200, 3)
    print(f"machine: {os.cpu_count()} CPUs (shared); BLAS threads pinned to 1\n")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rows = throughput(n_jobs, tmp, repeat)
        print(f"\n### Throughput ({n_jobs} lm calibrations of irb120, 30 + 50 poses; best of "
              f"{repeat} interleaved rounds)\n")
        print(format_table(rows))
        cov, per, study, elapsed = coverage(runs, [0.01, 0.05], tmp, workers=2)
        print(f"\n### Coverage of the 95 % intervals ({runs} Monte Carlo runs per noise level, "
              f"lm, irb120, 30 poses; {elapsed:.1f} s on 2 workers)\n")
        print(format_table(cov))
        print("\nper parameter (both noise levels), worst coverage first:\n")
        print(format_table(per))
        print("\n### Accuracy and time per job (median over the same runs)\n")
        print(format_table(study))


if __name__ == "__main__":
    main()
