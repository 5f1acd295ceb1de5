"""Study tables from batch results: accuracy and time per method and noise, and the
Monte Carlo coverage of the reported standard errors.

Coverage: for every simulated run and every free parameter, does the truth lie within
``identified +- z * std`` (``z = 1.96``, the two-sided 95 % normal quantile)? With
correct standard errors and a correct model the fraction tends to 95 %. The truth of a
parameter that is not identifiable from the poses is not estimable, so coverage studies
simulate errors only on the identifiable parameters (jobs with ``errors: identifiable``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kinecal._files import atomic_open
from kinecal.batch.records import JobRecord, read_result

__all__ = ["COVERAGE_ERRORS", "Z95", "coverage_estimable", "coverage_table", "format_table",
           "load_results", "parameter_coverage",
           "study_table", "write_table_csv"]

#: two-sided 95 % quantile of the standard normal distribution
Z95 = 1.959963984540054


def _key(noise: float | None, poses: int) -> tuple[float, int]:
    return (math.nan if noise is None else float(noise), int(poses))


def _nanmedian(values: list[float]) -> float:
    a = np.asarray(values, dtype=float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else math.nan


def study_table(records: Iterable[JobRecord]) -> list[dict[str, Any]]:
    """Median errors and time over seeds, per (method, noise, poses).

    Returns
    -------
    list of dict
        Rows ``{method, noise, poses, runs, failed, calibration_median,
        validation_median, seconds_median}`` (errors: mean distance error of each run in
        the model's length unit, median over the runs; seconds per job), sorted by
        method, noise and poses.
    """
    groups: dict[tuple[str, float, int], list[JobRecord]] = {}
    for rec in records:
        groups.setdefault((rec.method, *_key(rec.noise, rec.poses)), []).append(rec)
    rows = []
    for (method, noise, poses), recs in sorted(groups.items(), key=lambda kv: (
            kv[0][0], -1.0 if math.isnan(kv[0][1]) else kv[0][1], kv[0][2])):
        good = [r for r in recs if r.status in ("done", "resumed")]
        rows.append({
            "method": method, "noise": noise, "poses": poses, "runs": len(good),
            "failed": len(recs) - len(good),
            "calibration_median": _nanmedian([r.calibration_mean for r in good]),
            "validation_median": _nanmedian([r.validation_mean for r in good]),
            "seconds_median": _nanmedian([r.seconds for r in good]),
        })
    return rows


def load_results(out_dir: str | Path, records: Iterable[JobRecord]) -> list[dict[str, Any]]:
    """The result JSONs of the finished jobs among `records`."""
    out = Path(out_dir)
    results = []
    for rec in records:
        if rec.status in ("done", "resumed"):
            res = read_result(out / f"{rec.name}.json")
            if res is not None:
                results.append(res)
    return results


def _free_errors(result: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """``{name: (identified - truth, std)}`` of the free parameters of one run."""
    truth = result["truth"]
    return {name: (float(e["identified"]) - float(truth[name]), float(e["std"]))
            for name, e in result["parameters"].items() if e.get("free")}


#: a simulated job's ``errors`` under which its truth can be estimated: the deviations lie
#: only on the parameters the calibration identifies (``zero``: none at all)
COVERAGE_ERRORS = ("identifiable", "zero")


def coverage_estimable(result: dict[str, Any]) -> bool:
    """Whether a simulated job's result can check its standard errors against its truth:
    with ``errors: random`` the parameters held at nominal are off too, their errors land
    in confounded partners, and the identified values are biased by design."""
    job = result.get("job") or {}
    return bool(result.get("truth")) and job.get("errors", "random") in COVERAGE_ERRORS


def _run_coverage(result: dict[str, Any], z: float) -> tuple[int, int, list[float]] | None:
    """(covered, free parameters, normalised errors) of one run, None without truth or
    when its truth cannot be estimated (`coverage_estimable`)."""
    if not coverage_estimable(result):
        return None
    covered, n, zs = 0, 0, []
    for err, std in _free_errors(result).values():
        n += 1
        if std > 0 and math.isfinite(std):
            zs.append(err / std)
            covered += abs(err) <= z * std
    return covered, n, zs


def _z_stats(zs: np.ndarray) -> dict[str, float]:
    if not zs.size:
        return {"z_rms": math.nan, "z_median_abs": math.nan}
    return {"z_rms": float(np.sqrt(np.mean(zs * zs))),
            "z_median_abs": float(np.median(np.abs(zs)))}


def coverage_table(results: Iterable[dict[str, Any]], z: float = Z95) -> list[dict[str, Any]]:
    """Monte Carlo coverage of the ``+- z * std`` intervals, per (method, noise, poses).

    Parameters
    ----------
    results : iterable of dict
        Result JSONs of simulated jobs (with ``truth``); others, and those whose truth
        cannot be estimated (``errors: random``, `coverage_estimable`), are ignored.
    z : float
        Interval half-width in standard errors (default: 95 %).

    Returns
    -------
    list of dict
        Rows ``{method, noise, poses, runs, parameters, coverage, runs_all_covered,
        z_rms}``: ``coverage`` is the fraction of (run, free parameter) pairs whose truth
        lies in the interval, ``runs_all_covered`` the fraction of runs where every
        parameter is covered, ``z_rms`` the RMS of ``(identified - truth) / std`` (1 for
        correct standard errors) and ``z_median_abs`` its median absolute value (0.674
        for correct standard errors; insensitive to a few runs far off).
    """
    groups: dict[tuple[str, float, int], list[tuple[int, int, list[float]]]] = {}
    for res in results:
        cov = _run_coverage(res, z)
        if cov is None:
            continue
        job = res.get("job", {})
        key = (str(res.get("method")), *_key(job.get("noise"), res["calibration"]["n"]))
        groups.setdefault(key, []).append(cov)
    rows = []
    for (method, noise, poses), runs in sorted(groups.items()):
        covered = sum(c for c, _, _ in runs)
        total = sum(n for _, n, _ in runs)
        zs = np.concatenate([np.asarray(s, dtype=float) for _, _, s in runs])
        rows.append({
            "method": method, "noise": noise, "poses": poses, "runs": len(runs),
            "parameters": total, "coverage": covered / total if total else math.nan,
            "runs_all_covered": float(np.mean([c == n for c, n, _ in runs])),
            **_z_stats(zs),
        })
    return rows


def parameter_coverage(results: Iterable[dict[str, Any]], z: float = Z95,
                       ) -> list[dict[str, Any]]:
    """Coverage per free parameter over all runs with an estimable truth
    (`coverage_estimable`; worst coverage first).

    Returns
    -------
    list of dict
        Rows ``{parameter, runs, coverage, z_rms, z_median_abs}`` (``runs``: runs in
        which the parameter was free).
    """
    errs: dict[str, list[tuple[float, float]]] = {}
    for res in results:
        if coverage_estimable(res):
            for name, pair in _free_errors(res).items():
                errs.setdefault(name, []).append(pair)
    rows = []
    for name, pairs in errs.items():
        e, s = np.asarray(pairs, dtype=float).T
        ok = (s > 0) & np.isfinite(s)
        zs = e[ok] / s[ok]
        rows.append({"parameter": name, "runs": len(pairs),
                     "coverage": float(np.mean(np.abs(zs) <= z)) if zs.size else math.nan,
                     **_z_stats(zs)})
    return sorted(rows, key=lambda r: (r["coverage"], r["parameter"]))


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.4g}"
    return str(v)


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """Rows of dicts as a markdown table (empty string for no rows)."""
    if not rows:
        return ""
    cols = list(rows[0])
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(_cell(r[c]) for c in cols) + " |" for r in rows]
    return "\n".join(lines)


def write_table_csv(path: str | Path, rows: Sequence[dict[str, Any]]) -> None:
    """Write rows of dicts as CSV, atomically."""
    import csv

    with atomic_open(path, "w") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        if rows:
            writer.writerow(list(rows[0]))
            writer.writerows([[_cell(v) for v in r.values()] for r in rows])
