"""``kinecal batch``: run a jobs file on a local process pool or a Dask cluster."""

from __future__ import annotations

import math
import os
from pathlib import Path

import typer

from kinecal._limits import check_count
from kinecal.cli._app import app
from kinecal.errors import InputError

#: print every job's row up to this many jobs (the CSV always has them all)
MAX_PRINTED_ROWS = 40
#: memory of one worker process (numpy, scipy and kinecal imported: 75 MB measured, with a
#: margin for a job's arrays)
WORKER_BYTES = 200e6


def _row_text(rec) -> str:
    def num(v: float) -> str:
        return "" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.4g}"

    text = (f"{rec.name:32s} {rec.method:12s} {num(rec.calibration_mean):>10s} "
            f"{num(rec.validation_mean):>10s} {num(rec.seconds):>8s} {rec.status}")
    return text + (f"  {rec.error}" if rec.error else "")


def _print_warnings(records) -> None:
    """Each job's plausibility warnings, once, on stderr (also under ``--quiet``).

    ``kinecal: warning: JOB: MESSAGE [CODE]`` per job and warning when at most
    `MAX_PRINTED_ROWS` jobs warned; beyond that one line per code, with the number of jobs
    and the first job's message (``summary.csv`` names the codes of every job, each
    result JSON has the messages).
    """
    from kinecal.diagnostics import Diagnostic, format_warning

    warned = [r for r in records if r.warnings]
    if len(warned) <= MAX_PRINTED_ROWS:
        lines = [Diagnostic(w["code"], f"{r.name}: {w['message']}")
                 for r in warned for w in r.warnings]
    else:
        by_code: dict[str, list] = {}
        for r in warned:
            for w in r.warnings:
                by_code.setdefault(w["code"], []).append((r.name, w["message"]))
        lines = [Diagnostic(code, f"{len(hits)} of {len(records)} jobs (codes per job in "
                            f"summary.csv); the first, {hits[0][0]}: {hits[0][1]}")
                 for code, hits in by_code.items()]
    for d in lines:
        typer.echo(format_warning(d), err=True)


@app.command()
def batch(
    jobs_file: Path = typer.Argument(..., metavar="JOBS.yaml", help="Jobs file (YAML)."),
    out: Path = typer.Option(..., "--out", help="Output directory (results, summary.csv)."),
    executor: str = typer.Option("local", "--executor", metavar="[local|dask]",
                                 help="A local process pool or a Dask cluster."),
    scheduler: str | None = typer.Option(None, "--scheduler",
                                         help="Dask scheduler address (tcp://host:port)."),
    workers: int | None = typer.Option(None, "--workers",
                                       help="Worker processes (default: CPU count)."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bar."),
    register: bool = typer.Option(False, "--register", help="Record each measured job's "
                                  "result in the registry, for its serial (the job's serial "
                                  "key, else its name) as it finishes (docs/robot-life.md)."),
    db: str | None = typer.Option(None, "--db", help="With --register: the registry "
                                  "(default $KINECAL_DB, else kinecal.db)."),
) -> None:
    """Run many calibrations (a fleet or a study); resumable, one JSON per job."""
    from kinecal.batch import load_jobs
    from kinecal.batch.inputs import check_batch_paths

    _check_options(executor, scheduler, workers, jobs_file)
    if db is not None and not register:
        raise InputError("applies to --register only", option="--db")
    jobs = load_jobs(jobs_file)
    check_batch_paths(jobs, out, [jobs_file])
    recorder = None
    if register:
        from kinecal.cli._registry_batch import BatchRecorder

        recorder = BatchRecorder(jobs, out, db)
    result = _run(jobs, jobs_file, out, executor, scheduler, workers, quiet, recorder)
    if recorder is not None:
        recorder.say()
    records = result.records
    _print_results(records, out, quiet)
    _print_warnings(records)
    counts = ", ".join(f"{n} {s}" for s, n in sorted(result.counts.items()))
    typer.echo(f"{len(records)} jobs: {counts}; summary in {result.summary_path}", err=True)
    failed = [r for r in records if r.status != "done" and r.status != "resumed"]
    if failed:
        # exit 2 when every failure is a user mistake (bad file, bad option), 1 otherwise
        raise typer.Exit(2 if all(r.kind == "input" for r in failed) else 1)


def _check_options(executor: str, scheduler: str | None, workers: int | None,
                   jobs_file: Path) -> None:
    if executor not in ("local", "dask"):
        raise InputError(f"expected local or dask, got {executor!r}", option="--executor")
    if scheduler is not None and executor != "dask":
        raise InputError("--scheduler needs --executor dask", option="--scheduler")
    if workers is not None and workers < 1:
        raise InputError(f"expected a positive number of workers, got {workers}",
                         option="--workers")
    if workers is not None and workers > 4 * (os.cpu_count() or 1):
        raise InputError(f"{workers} worker processes for {os.cpu_count()} CPUs: the jobs are "
                         f"CPU-bound, more than {4 * (os.cpu_count() or 1)} only compete for "
                         "the cores", option="--workers")
    if workers is not None:  # each worker process holds numpy, scipy and a job's arrays
        check_count(workers, "--workers", bytes_per_item=WORKER_BYTES, what="worker processes")
    if workers is not None and scheduler is not None:
        raise InputError("the workers of a running Dask cluster are the scheduler's; "
                         "--workers applies to a local pool or a local Dask cluster",
                         option="--workers")
    if jobs_file.is_dir():
        raise InputError(f"{jobs_file} is a directory, expected a jobs file (YAML)",
                         option="JOBS.yaml")


def _run(jobs, jobs_file: Path, out: Path, executor: str, scheduler: str | None,
         workers: int | None, quiet: bool, recorder=None):
    """`run_batch` with a progress bar; an interrupt says how to resume."""
    import contextlib

    from kinecal.batch import dask_executor, run_batch
    from kinecal.cli._common import progress
    from kinecal.cli._signals import Terminated

    with contextlib.ExitStack() as stack:
        ex = None
        if executor == "dask":
            ex = stack.enter_context(dask_executor(scheduler, workers))
        update = stack.enter_context(progress(f"batch {jobs_file.name}", len(jobs), quiet))
        settled: list[str] = []

        def on_result(rec) -> None:
            settled.append(rec.status)
            if recorder is not None:
                recorder(rec)
            update(1)

        try:
            return run_batch(jobs, out, executor=ex, workers=workers, on_result=on_result,
                             inputs=[jobs_file])
        except (KeyboardInterrupt, Terminated) as exc:
            finished = sum(s in ("done", "resumed") for s in settled)
            # `kinecal.cli.main` adds "kinecal: interrupted" (130) or "... terminated" (143)
            typer.echo(f"{finished} of {len(jobs)} jobs have results in {out} (summary in "
                       f"{out / 'summary.csv'}); run the same command again to resume",
                       err=True)
            raise typer.Exit(143 if isinstance(exc, Terminated) else 130) from None


def _coverage_note(results: list[dict]) -> str | None:
    """Why coverage.csv leaves out simulated jobs (``errors: random``: parameters held at
    nominal are off too, their errors land in confounded partners, so the identified
    values cannot check the standard errors), or None when it leaves none out."""
    from kinecal.batch.tables import COVERAGE_ERRORS, coverage_estimable

    left = [r for r in results if r.get("truth") and not coverage_estimable(r)]
    if not left:
        return None
    what = ("no coverage table" if len(left) == len(results) else
            f"the coverage table leaves out {len(left)} of {len(results)} jobs")
    return (f"({what}: jobs with errors: {(left[0].get('job') or {}).get('errors', 'random')}"
            " have errors on parameters the poses cannot identify, so their standard errors "
            f"cannot be checked against the truth; a coverage study needs errors: "
            f"{' or '.join(COVERAGE_ERRORS)}, docs/batch.md)")


def _print_results(records, out: Path, quiet: bool) -> None:
    """The job table (failed jobs only beyond `MAX_PRINTED_ROWS`), and for simulated
    studies ``study.csv`` and ``coverage.csv`` with their tables."""
    from kinecal.batch import coverage_table, format_table, load_results, study_table
    from kinecal.batch.tables import write_table_csv

    if not quiet:
        if len(records) <= MAX_PRINTED_ROWS:
            typer.echo(f"{'job':32s} {'method':12s} {'cal. mean':>10s} {'val. mean':>10s} "
                       f"{'seconds':>8s} status")
            for rec in records:
                typer.echo(_row_text(rec))
        else:
            for rec in records:
                if rec.status == "failed":
                    typer.echo(_row_text(rec))
    simulated = [r for r in records if r.noise is not None]
    if simulated:
        rows = study_table(simulated)
        write_table_csv(out / "study.csv", rows)
        results = load_results(out, simulated)
        cov = coverage_table(results)
        if cov:
            write_table_csv(out / "coverage.csv", cov)
        if not quiet:
            typer.echo("\nmedian over seeds (errors in the model's length unit, seconds per "
                       "job):\n" + format_table(rows))
            if cov:
                typer.echo("\ncoverage of the 95 % intervals (identified +- 1.96 std):\n"
                           + format_table(cov))
            note = _coverage_note(results)
            if note is not None:
                typer.echo(note)
