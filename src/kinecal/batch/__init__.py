"""Batch runs: many calibrations (a fleet of arms, or a simulation study) on a process pool
or a Dask cluster, resumable, with one result file per job and a summary.

>>> from kinecal.batch import load_jobs, run_batch
>>> jobs = load_jobs("jobs.yaml")                      # doctest: +SKIP
>>> out = run_batch(jobs, "results", workers=2)        # doctest: +SKIP
>>> out.counts                                         # doctest: +SKIP
{'done': 12}

See docs/batch.md for the jobs file and the guarantees (atomic per-job output, resume,
failure recording, retry of jobs whose worker died).
"""

from __future__ import annotations

from kinecal.batch.executors import dask_executor, local_executor
from kinecal.batch.jobs import Job, JobsFile, Study, expand_study, load_jobs, parse_jobs
from kinecal.batch.records import BatchResult, JobRecord, read_result, write_summary
from kinecal.batch.runner import run_batch
from kinecal.batch.tables import (
    coverage_table,
    format_table,
    load_results,
    parameter_coverage,
    study_table,
)
from kinecal.batch.work import run_job

__all__ = [
    "BatchResult",
    "Job",
    "JobRecord",
    "JobsFile",
    "Study",
    "coverage_table",
    "dask_executor",
    "expand_study",
    "format_table",
    "load_jobs",
    "load_results",
    "local_executor",
    "parameter_coverage",
    "parse_jobs",
    "read_result",
    "run_batch",
    "run_job",
    "study_table",
    "write_summary",
]
