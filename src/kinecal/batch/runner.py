"""`run_batch`: many calibrations on any `concurrent.futures.Executor`, resumable.

Guarantees
----------
- Each finished job's result is written atomically to ``DIR/<name>.json`` as soon as it
  arrives (by this process: the workers need no access to ``DIR``).
- A rerun skips every job whose result file exists and records the same job
  specification and the same input hash: a SHA-256 of the specification and of the bytes
  of every file the job reads (resume); a job whose specification, model or measurement
  files changed is recomputed.
- Before any job runs, a batch whose result files would overwrite one of its inputs (or
  the jobs file) is refused (`kinecal.batch.inputs.check_batch_paths`).
- A failed job (bad file, solver error) is recorded with its error in ``summary.csv``;
  the others go on. A rerun tries it again.
- A job whose worker process died (``os._exit``, SIGKILL, out of memory) is resubmitted:
  a broken process pool is replaced by a new one; Dask reschedules such a task by itself
  and a `KilledWorker` error is resubmitted here. After `max_attempts` deaths the job is
  recorded as failed.
- ``DIR/summary.csv`` (one row per job, in the jobs file's order) is written at the end,
  also when the run is interrupted (unfinished jobs then have status ``not run``); the
  workers of the default process pool are then killed, not left to finish their jobs.
  Workers also end by themselves when the coordinating process dies (SIGKILL): see
  `kinecal.batch.executors.local_executor`.
"""

from __future__ import annotations

import collections
import contextlib
import json
import math
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, CancelledError, Executor, wait
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinecal._files import atomic_open, write_text_atomic
from kinecal.batch.inputs import check_batch_paths, input_hash
from kinecal.batch.jobs import Job
from kinecal.batch.work import run_job

__all__ = ["BatchResult", "JobRecord", "read_result", "run_batch", "write_summary"]

#: exception type names that mean "the worker died", not "the job failed"
_WORKER_DEATH = ("KilledWorker", "BrokenProcessPool", "BrokenExecutor", "WorkerLost")


@dataclass
class JobRecord:
    """One row of ``summary.csv``.

    ``status`` is ``done`` (computed now), ``resumed`` (result found from an earlier
    run), ``failed`` or ``not run`` (interrupted). Means are mean distance errors in the
    model's length unit (NaN when unknown); ``seconds`` is the job's time in its worker;
    ``warnings`` the job's plausibility warnings ``[{code, message}]`` (in the CSV: the
    codes, joined by ``;``).
    """

    name: str
    method: str
    seed: int
    noise: float | None
    poses: int
    calibration_mean: float = math.nan
    validation_mean: float = math.nan
    seconds: float = math.nan
    status: str = "not run"
    error: str = ""
    attempts: int = 0
    kind: str = ""
    warnings: list[dict[str, str]] = field(default_factory=list)

    @classmethod
    def from_job(cls, job: Job) -> JobRecord:
        """A record of `job` that has not run."""
        return cls(name=job.name, method=job.method, seed=job.seed,
                   noise=job.noise if job.simulated else None, poses=job.poses or 0)

    def fill(self, result: dict[str, Any], seconds: float, status: str) -> None:
        """Copy the numbers of a calibration JSON into the record."""
        self.poses = int(result["calibration"]["n"])
        self.calibration_mean = float(result["calibration"]["after"]["mean"])
        val = result.get("validation")
        self.validation_mean = float(val["after"]["mean"]) if val else math.nan
        self.seconds = float(seconds)
        self.status = status
        self.warnings = _warning_list(result.get("warnings"))


@dataclass
class BatchResult:
    """Outcome of `run_batch`: the records (jobs file order) and the output paths."""

    records: list[JobRecord]
    out_dir: Path
    summary_path: Path

    @property
    def counts(self) -> dict[str, int]:
        """Number of jobs per status."""
        return dict(collections.Counter(r.status for r in self.records))

    @property
    def ok(self) -> bool:
        """True when every job has a result."""
        return all(r.status in ("done", "resumed") for r in self.records)


def _warning_list(items: Any) -> list[dict[str, str]]:
    """``[{code, message}]`` from a result's or an outcome's ``warnings`` (anything else
    in an old or edited result file is ignored)."""
    if not isinstance(items, list):
        return []
    return [{"code": str(w["code"]), "message": str(w.get("message", ""))} for w in items
            if isinstance(w, dict) and "code" in w]


SUMMARY_COLUMNS = ("name", "method", "seed", "noise", "poses", "calibration_mean",
                   "validation_mean", "seconds", "status", "error", "warnings")


def write_summary(path: str | Path, records: Iterable[JobRecord]) -> None:
    """Write ``summary.csv`` atomically (columns `SUMMARY_COLUMNS`)."""
    import csv

    with atomic_open(path, "w") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(SUMMARY_COLUMNS)
        for rec in records:
            row = asdict(rec)
            out = []
            for col in SUMMARY_COLUMNS:
                v = row[col]
                if col == "warnings":
                    out.append(";".join(dict.fromkeys(w["code"] for w in v)))
                elif v is None or (isinstance(v, float) and math.isnan(v)):
                    out.append("")
                elif isinstance(v, float):
                    out.append(f"{v:.6g}" if col == "seconds" else repr(v))
                else:
                    out.append(str(v))
            writer.writerow(out)


def read_result(path: str | Path) -> dict[str, Any] | None:
    """The result JSON at `path`, or None when missing or unreadable (not finished)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return str(obj)


def _is_worker_death(exc: BaseException) -> bool:
    return isinstance(exc, BrokenExecutor) or type(exc).__name__ in _WORKER_DEATH


def run_batch(
    jobs: Sequence[Job],
    out_dir: str | Path,
    *,
    executor: Executor | Callable[[], Executor] | None = None,
    workers: int | None = None,
    max_attempts: int = 3,
    window: int | None = None,
    on_result: Callable[[JobRecord], Any] | None = None,
    job_function: Callable[[Job], dict[str, Any]] = run_job,
    inputs: Sequence[str | Path] = (),
) -> BatchResult:
    """Run `jobs`, writing ``out_dir/<name>.json`` per job and ``out_dir/summary.csv``.

    Parameters
    ----------
    jobs : sequence of Job
        The jobs (names unique), e.g. from `kinecal.batch.load_jobs`.
    out_dir : str or Path
        Output directory (created). Results already there are reused (resume).
    executor : Executor or callable, optional
        Where jobs run: an executor (not shut down here), or a factory returning a fresh
        one (used again when a process pool breaks). Default: a local process pool
        (`kinecal.batch.local_executor`) of `workers` processes.
    workers : int, optional
        Size of the default process pool.
    max_attempts : int
        A job whose worker dies is tried at most this often.
    window : int, optional
        At most this many jobs submitted at a time (default: 2 per worker for the
        default pool, all jobs otherwise). A dying pool fails every submitted job, so a
        window bounds the retries one death causes.
    on_result : callable, optional
        Called with each job's `JobRecord` when it is settled (resumed, done, failed).
    job_function : callable
        The function run per job (default `kinecal.batch.work.run_job`); it must be
        picklable by the executor and return `run_job`'s outcome dict.
    inputs : sequence of path
        Further files the batch must never overwrite (the jobs file); the jobs' own
        model, data and validation files are always protected.

    Returns
    -------
    BatchResult
    """
    from kinecal.batch.executors import local_executor

    out = Path(out_dir)
    check_batch_paths(jobs, out, inputs)
    out.mkdir(parents=True, exist_ok=True)
    records = {job.name: JobRecord.from_job(job) for job in jobs}
    digests: dict = {}
    hashes = {job.name: input_hash(job, digests) for job in jobs}

    def settle(rec: JobRecord) -> None:
        if on_result is not None:
            on_result(rec)

    todo: collections.deque[Job] = collections.deque()
    for job in jobs:
        prev = read_result(out / f"{job.name}.json")
        if (prev is not None and prev.get("job") == job.spec()
                and (prev.get("batch") or {}).get("input_hash") == hashes[job.name]):
            records[job.name].fill(prev, prev.get("batch", {}).get("seconds", math.nan),
                                   "resumed")
            settle(records[job.name])
        else:
            todo.append(job)

    factory: Callable[[], Executor] | None
    if executor is None:
        factory = lambda: local_executor(workers)  # noqa: E731
        window = window or 2 * (workers or _cpu_count())
        current: Executor | None = None
    elif isinstance(executor, Executor):
        factory, current = None, executor
    else:
        factory, current = executor, None
    owned = factory is not None
    inflight: dict[Any, Job] = {}

    def handle(fut: Any, job: Job) -> bool:
        """Settle a finished future; True when its worker died."""
        rec = records[job.name]
        rec.attempts += 1
        try:
            outcome = fut.result()
        except CancelledError:
            outcome = None
            exc: BaseException | None = RuntimeError("cancelled")
        except Exception as err:  # anything raised (pickling, scheduler) is recorded
            outcome, exc = None, err
        else:
            exc = None
        if exc is not None and _is_worker_death(exc):
            if rec.attempts < max_attempts:
                todo.appendleft(job)
                return isinstance(exc, BrokenExecutor)
            rec.status, rec.kind = "failed", "internal"
            rec.error = f"worker died {rec.attempts} times ({type(exc).__name__})"
        elif exc is not None:
            rec.status, rec.kind = "failed", "internal"
            rec.error = f"{type(exc).__name__}: {exc}"
        elif outcome["status"] == "done":
            result = outcome["result"]
            result["batch"] = {"seconds": outcome["seconds"], "attempts": rec.attempts,
                               "input_hash": hashes[job.name]}
            text = json.dumps(result, indent=2, default=_json_default, allow_nan=True)
            try:
                write_text_atomic(out / f"{job.name}.json", text + "\n")
            except OSError as err:  # e.g. disk full: this job has no result, go on
                rec.status, rec.kind = "failed", "internal"
                rec.error = f"cannot write {job.name}.json: {err}"
            else:
                rec.fill(result, outcome["seconds"], "done")
        else:
            rec.status, rec.error, rec.kind = "failed", outcome["error"], outcome["kind"]
            rec.seconds = outcome["seconds"]
            rec.warnings = _warning_list(outcome.get("warnings"))
        settle(rec)
        return isinstance(exc, BrokenExecutor)

    try:
        while todo or inflight:
            if current is None:
                current = factory()  # type: ignore[misc]
            broken = False
            while todo and (window is None or len(inflight) < window):
                job = todo.popleft()
                try:
                    inflight[current.submit(job_function, job)] = job
                except BrokenExecutor:
                    todo.appendleft(job)
                    broken = True
                    break
            if inflight and not broken:
                done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
                for fut in done:
                    broken |= handle(fut, inflight.pop(fut))
            if broken:
                # a broken pool fails every job it holds: collect them, then replace it
                done, _ = wait(list(inflight))
                for fut in done:
                    handle(fut, inflight.pop(fut))
                if owned:
                    _shutdown(current, wait=False)
                    current = None
                else:  # a given executor cannot be replaced
                    for job in todo:
                        rec = records[job.name]
                        rec.status, rec.kind = "failed", "internal"
                        rec.error = "the executor broke (a worker died)"
                        settle(rec)
                    todo.clear()
    finally:
        interrupted = bool(todo or inflight)
        for fut in inflight:
            fut.cancel()
        if owned and current is not None:
            if interrupted:
                _kill_workers(current)
            _shutdown(current, wait=not interrupted)
        summary = out / "summary.csv"
        write_summary(summary, [records[job.name] for job in jobs])
    return BatchResult([records[job.name] for job in jobs], out, summary)


def _cpu_count() -> int:
    import os

    return os.cpu_count() or 1


def _kill_workers(executor: Executor) -> None:
    """Kill the worker processes of an interrupted process pool (their jobs are lost
    anyway: without this, the interpreter's exit would wait for them to finish)."""
    kill = getattr(executor, "kill_workers", None)  # Python >= 3.14
    if callable(kill):
        kill()
        return
    # before 3.14: the pool's process table (emptied by shutdown(), so kill first)
    procs = list((getattr(executor, "_processes", None) or {}).values())
    for p in procs:
        with contextlib.suppress(Exception):
            p.kill()
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout=5)


def _shutdown(executor: Executor, wait: bool) -> None:
    """Shut `executor` down, cancelling queued jobs where the executor supports it."""
    try:
        executor.shutdown(wait=wait, cancel_futures=True)
    except TypeError:  # e.g. Dask's ClientExecutor: no cancel_futures (wait=False cancels)
        executor.shutdown(wait=wait)
