"""kinecal.batch: jobs-file schema, study expansion, per-job work, study tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinecal.batch import (
    Job,
    coverage_table,
    load_jobs,
    parameter_coverage,
    parse_jobs,
    run_job,
    study_table,
)
from kinecal.batch.records import JobRecord
from kinecal.batch.tables import Z95
from kinecal.errors import InputError


def _write(tmp_path, text):
    path = tmp_path / "jobs.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_study_grid_expands_in_order_with_unique_names(tmp_path):
    path = _write(tmp_path, """
jobs:
  - {name: arm-0001, model: irb120, data: arm.csv, validate: arm-val.csv, method: householder}
study:
  {model: irb120, methods: [lm, hybrid-ga], seeds: [0, 1, 2], noise: [0.01, 0.02],
   poses: [30], validation_poses: 100}
""")
    jobs = load_jobs(path)
    assert len(jobs) == 1 + 2 * 3 * 2
    assert jobs[0].name == "arm-0001" and not jobs[0].simulated
    # relative paths are made absolute against the jobs file's directory
    assert jobs[0].data == str((tmp_path / "arm.csv").resolve())
    assert jobs[0].validation == str((tmp_path / "arm-val.csv").resolve())
    assert jobs[0].model == "irb120"  # bundled name kept
    names = [j.name for j in jobs[1:]]
    assert names[:3] == ["irb120-lm-n0.01-p30-s0", "irb120-lm-n0.01-p30-s1",
                         "irb120-lm-n0.01-p30-s2"]
    assert names[-1] == "irb120-hybrid-ga-n0.02-p30-s2"
    assert len(set(names)) == len(names)
    assert all(j.simulated and j.validation_poses == 100 and j.poses == 30 for j in jobs[1:])
    # the spec recorded in each result round-trips through the schema
    assert Job.model_validate(jobs[0].spec()) == jobs[0]


def test_seed_count_and_list_of_studies():
    jobs = parse_jobs({"study": [{"model": "ur5", "seeds": 4, "poses": [10, 20], "name": "a"},
                                 {"model": "ur5", "seeds": [7], "poses": [10], "name": "b"}]})
    assert [j.seed for j in jobs[:4]] == [0, 1, 2, 3]
    assert [j.poses for j in jobs[:8:4]] == [10, 20]
    assert jobs[-1].name == "b-lm-n0-p10-s7"


@pytest.mark.parametrize("doc, words", [
    ({"jobs": [{"name": "a", "model": "irb120"}]}, "either 'data'"),
    ({"jobs": [{"name": "a", "model": "irb120", "data": "x.csv", "poses": 5}]}, "either"),
    ({"jobs": [{"name": "a", "model": "irb120", "poses": 5, "method": "nope"}]}, "unknown method"),
    ({"jobs": [{"name": "a/b", "model": "irb120", "poses": 5}]}, "jobs.0.name"),
    ({"jobs": [{"name": "a", "model": "irb120", "poses": 5, "colour": 1}]}, "colour"),
    ({"jobs": [{"name": "a", "model": "irb120", "poses": 5},
               {"name": "a", "model": "irb120", "poses": 6}]}, "used twice"),
    ({"study": {"model": "irb120", "poses": [10], "noise": [-1.0]}}, "noise"),
    ({"jobs": []}, "no jobs"),
    ([1, 2], "mapping"),
])
def test_bad_jobs_files_raise_input_error_naming_the_file(tmp_path, doc, words):
    with pytest.raises(InputError) as err:
        parse_jobs(doc, tmp_path, tmp_path / "jobs.yaml")
    assert words in str(err.value)
    assert "jobs.yaml" in str(err.value)


def test_unreadable_yaml_and_missing_file(tmp_path):
    with pytest.raises(InputError, match="not valid YAML"):
        load_jobs(_write(tmp_path, "jobs: [unclosed"))
    with pytest.raises(InputError, match="file not found"):
        load_jobs(tmp_path / "missing.yaml")


def test_noise_free_identifiable_job_recovers_its_truth():
    job = Job(name="t", model="irb120", poses=25, validation_poses=20, noise=0.0,
              errors="identifiable", seed=3)
    out = run_job(job)
    assert out["status"] == "done", out["error"]
    res = out["result"]
    assert res["job"] == job.spec()
    free = [n for n, p in res["parameters"].items() if p["free"]]
    assert len(free) == res["rank"] == 20
    # the errors sit exactly on the free (identifiable) parameters
    moved = [n for n, p in res["parameters"].items() if res["truth"][n] != p["nominal"]]
    assert moved == free
    for name, p in res["parameters"].items():
        # errors only on identifiable parameters: everything, free or held, equals its truth
        assert p["identified"] == pytest.approx(res["truth"][name], abs=1e-6)
    assert res["validation"]["after"]["mean"] < 1e-6 < res["validation"]["before"]["mean"]


def test_same_seed_same_arm_across_methods_and_failed_job_is_reported(tmp_path):
    a = run_job(Job(name="a", model="irb120", poses=15, noise=0.01, seed=5))["result"]
    b = run_job(Job(name="b", model="irb120", poses=15, noise=0.01, seed=5,
                    method="householder"))["result"]
    c = run_job(Job(name="c", model="irb120", poses=15, noise=0.01, seed=6))["result"]
    assert a["truth"] == b["truth"] != c["truth"]
    assert a["calibration"]["before"] == b["calibration"]["before"]
    bad = run_job(Job(name="d", model="irb120", data=str(tmp_path / "none.csv")))
    assert bad["status"] == "failed" and bad["kind"] == "input"
    assert "none.csv" in bad["error"] and "not found" in bad["error"]


def _result(method, noise, identified, std, truth, n=30):
    return {"method": method, "job": {"noise": noise, "errors": "identifiable"},
            "calibration": {"n": n},
            "truth": {f"p{k}": t for k, t in enumerate(truth)},
            "parameters": {f"p{k}": {"identified": v, "std": s, "free": True}
                           for k, (v, s) in enumerate(zip(identified, std, strict=True))}}


def test_coverage_table_counts_truths_inside_the_intervals():
    inside = _result("lm", 0.01, [1.0, 2.0], [0.1, 0.1], [1.0 + 0.19, 2.0 - 0.05])
    outside = _result("lm", 0.01, [1.0, 2.0], [0.1, 0.1], [1.0 + 0.2, 2.0])
    other = _result("lm", 0.02, [0.0], [1.0], [0.5])
    rows = coverage_table([inside, outside, other, {"method": "lm", "parameters": {}}])
    assert [(r["noise"], r["runs"], r["parameters"]) for r in rows] == [(0.01, 2, 4),
                                                                     (0.02, 1, 1)]
    assert rows[0]["coverage"] == pytest.approx(3 / 4)
    assert rows[0]["runs_all_covered"] == pytest.approx(0.5)
    z = np.array([1.9, -0.5, 2.0, 0.0])
    assert rows[0]["z_rms"] == pytest.approx(np.sqrt(np.mean(z * z)))
    assert rows[0]["z_median_abs"] == pytest.approx(np.median(np.abs(z)))
    assert 0.19 / 0.1 < Z95 < 0.2 / 0.1
    per = parameter_coverage([inside, outside, other])
    assert [(r["parameter"], r["runs"], r["coverage"]) for r in per] == [
        ("p0", 3, pytest.approx(2 / 3)), ("p1", 2, 1.0)]
    # errors: random (the default) leaves confounded partners biased: not counted at all
    random = {**outside, "job": {"noise": 0.01}}
    assert coverage_table([random]) == [] and parameter_coverage([random]) == []
    assert coverage_table([inside, random])[0]["runs"] == 1


def test_study_table_medians_over_seeds_skip_failures():
    recs = [JobRecord("a", "lm", s, 0.01, 30, calibration_mean=c, validation_mean=v,
                      seconds=t, status="done")
            for s, (c, v, t) in enumerate([(1.0, 2.0, 0.1), (3.0, 4.0, 0.3), (2.0, 9.0, 0.2)])]
    recs.append(JobRecord("b", "lm", 9, 0.01, 30, status="failed", error="x"))
    recs.append(JobRecord("c", "ga", 0, 0.01, 30, 5.0, 6.0, 1.0, "resumed"))
    rows = study_table(recs)
    assert [r["method"] for r in rows] == ["ga", "lm"]
    lm = rows[1]
    assert (lm["runs"], lm["failed"]) == (3, 1)
    assert (lm["calibration_median"], lm["validation_median"], lm["seconds_median"]) == (
        2.0, 4.0, 0.2)
    assert not math.isnan(rows[0]["validation_median"])
