"""The records of a batch: one `JobRecord` per job, ``summary.csv``, the result files.

`kinecal.batch.runner` fills them as jobs settle; `kinecal.batch.tables` reads them back.
"""

from __future__ import annotations

import collections
import json
import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from kinecal._files import atomic_open
from kinecal.batch.jobs import Job

__all__ = ["SUMMARY_COLUMNS", "BatchResult", "JobRecord", "read_result", "warning_list",
           "write_summary"]


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
        self.warnings = warning_list(result.get("warnings"))


@dataclass(repr=False)
class BatchResult:
    """Outcome of `run_batch`: the records (jobs file order) and the output paths."""

    records: list[JobRecord]
    out_dir: Path
    summary_path: Path

    def __repr__(self) -> str:
        counts = ", ".join(f"{n} {s}" for s, n in sorted(self.counts.items()))
        return f"<BatchResult {len(self.records)} jobs in {self.out_dir}: {counts}>"

    @property
    def counts(self) -> dict[str, int]:
        """Number of jobs per status."""
        return dict(collections.Counter(r.status for r in self.records))

    @property
    def ok(self) -> bool:
        """True when every job has a result."""
        return all(r.status in ("done", "resumed") for r in self.records)


def warning_list(items: Any) -> list[dict[str, str]]:
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
