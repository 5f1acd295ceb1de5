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
  the jobs file) is refused (`kinecal.batch.inputs.check_batch_paths`), and so is a second
  batch into a folder another one is writing into (`kinecal.batch.lock.folder_lock`).
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
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, CancelledError, Executor, wait
from pathlib import Path
from typing import Any

import numpy as np

from kinecal._files import write_text_atomic
from kinecal.batch.inputs import check_batch_paths, input_hash
from kinecal.batch.jobs import Job
from kinecal.batch.lock import folder_lock
from kinecal.batch.records import (
    BatchResult,
    JobRecord,
    read_result,
    warning_list,
    write_summary,
)
from kinecal.batch.work import run_job

__all__ = ["run_batch"]

#: exception type names that mean "the worker died", not "the job failed"
_WORKER_DEATH = ("KilledWorker", "BrokenProcessPool", "BrokenExecutor", "WorkerLost")


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

    Raises
    ------
    InputError
        Outputs that would overwrite inputs, or another batch running into `out_dir`
        (`kinecal.batch.lock.folder_lock`).
    """
    out = Path(out_dir)
    check_batch_paths(jobs, out, inputs)
    out.mkdir(parents=True, exist_ok=True)
    with folder_lock(out):  # a second batch into `out` is refused, not run twice
        return _run_locked(jobs, out, executor, workers, max_attempts, window, on_result,
                           job_function)


def _run_locked(jobs: Sequence[Job], out: Path, executor, workers: int | None,
                max_attempts: int, window: int | None, on_result, job_function
                ) -> BatchResult:
    """`run_batch` once the output folder is checked, made and locked."""
    from kinecal.batch.executors import local_executor

    run = _Run(jobs, out, max_attempts, on_result)
    factory: Callable[[], Executor] | None
    if executor is None:
        factory = lambda: local_executor(workers)  # noqa: E731
        window = window or 2 * (workers or _cpu_count())
        current: Executor | None = None
    elif isinstance(executor, Executor):
        factory, current = None, executor
    else:
        factory, current = executor, None
    try:
        run.drive(factory, current, window, job_function)
    finally:
        run.close()
        summary = out / "summary.csv"
        write_summary(summary, [run.records[job.name] for job in jobs])
    return BatchResult([run.records[job.name] for job in jobs], out, summary)


class _Run:
    """The state of one `run_batch`: records, jobs to do, jobs in flight, the executor."""

    def __init__(self, jobs: Sequence[Job], out: Path, max_attempts: int,
                 on_result: Callable[[JobRecord], Any] | None) -> None:
        self.out, self.max_attempts, self.on_result = out, max_attempts, on_result
        self.records = {job.name: JobRecord.from_job(job) for job in jobs}
        digests: dict = {}
        self.hashes = {job.name: input_hash(job, digests) for job in jobs}
        self.inflight: dict[Any, Job] = {}
        self.current: Executor | None = None
        self.owned = False
        self.todo: collections.deque[Job] = collections.deque()
        for job in jobs:  # resume: a result of the same job and inputs is kept
            prev = read_result(out / f"{job.name}.json")
            if (prev is not None and prev.get("job") == job.spec()
                    and (prev.get("batch") or {}).get("input_hash") == self.hashes[job.name]):
                self.records[job.name].fill(
                    prev, prev.get("batch", {}).get("seconds", math.nan), "resumed")
                self.settle(self.records[job.name])
            else:
                self.todo.append(job)

    def settle(self, rec: JobRecord) -> None:
        if self.on_result is not None:
            self.on_result(rec)

    def handle(self, fut: Any, job: Job) -> bool:
        """Settle a finished future; True when its worker died."""
        rec = self.records[job.name]
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
            if rec.attempts < self.max_attempts:
                self.todo.appendleft(job)
                return isinstance(exc, BrokenExecutor)
            rec.status, rec.kind = "failed", "internal"
            rec.error = f"worker died {rec.attempts} times ({type(exc).__name__})"
        elif exc is not None:
            rec.status, rec.kind = "failed", "internal"
            rec.error = f"{type(exc).__name__}: {exc}"
        elif outcome["status"] == "done":
            self._write(job, rec, outcome)
        else:
            rec.status, rec.error, rec.kind = "failed", outcome["error"], outcome["kind"]
            rec.seconds = outcome["seconds"]
            rec.warnings = warning_list(outcome.get("warnings"))
        self.settle(rec)
        return isinstance(exc, BrokenExecutor)

    def _write(self, job: Job, rec: JobRecord, outcome: dict[str, Any]) -> None:
        result = outcome["result"]
        result["batch"] = {"seconds": outcome["seconds"], "attempts": rec.attempts,
                           "input_hash": self.hashes[job.name]}
        text = json.dumps(result, indent=2, default=_json_default, allow_nan=True)
        try:
            write_text_atomic(self.out / f"{job.name}.json", text + "\n")
        except OSError as err:  # e.g. disk full: this job has no result, go on
            rec.status, rec.kind = "failed", "internal"
            rec.error = f"cannot write {job.name}.json: {err}"
        else:
            rec.fill(result, outcome["seconds"], "done")

    def drive(self, factory: Callable[[], Executor] | None, current: Executor | None,
              window: int | None, job_function: Callable[[Job], dict[str, Any]]) -> None:
        """Submit, wait and settle until every job is settled."""
        self.current, self.owned = current, factory is not None
        todo, inflight = self.todo, self.inflight
        while todo or inflight:
            if self.current is None:
                self.current = factory()  # type: ignore[misc]
            broken = False
            while todo and (window is None or len(inflight) < window):
                job = todo.popleft()
                try:
                    inflight[self.current.submit(job_function, job)] = job
                except BrokenExecutor:
                    todo.appendleft(job)
                    broken = True
                    break
            if inflight and not broken:
                done, _ = wait(list(inflight), return_when=FIRST_COMPLETED)
                for fut in done:
                    broken |= self.handle(fut, inflight.pop(fut))
            if broken:
                self._replace_broken()

    def _replace_broken(self) -> None:
        """A broken pool fails every job it holds: collect them, then replace it (or, for
        an executor given by the caller, which cannot be replaced, fail the rest)."""
        done, _ = wait(list(self.inflight))
        for fut in done:
            self.handle(fut, self.inflight.pop(fut))
        if self.owned:
            _shutdown(self.current, wait=False)
            self.current = None
            return
        for job in self.todo:
            rec = self.records[job.name]
            rec.status, rec.kind = "failed", "internal"
            rec.error = "the executor broke (a worker died)"
            self.settle(rec)
        self.todo.clear()

    def close(self) -> None:
        """Cancel what is in flight; an interrupted pool of ours has its workers killed."""
        interrupted = bool(self.todo or self.inflight)
        for fut in self.inflight:
            fut.cancel()
        if self.owned and self.current is not None:
            if interrupted:
                _kill_workers(self.current)
            _shutdown(self.current, wait=not interrupted)


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
