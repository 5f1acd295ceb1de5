"""Jobs-file keys of the second wave (error_model, harmonics, folds, sigma, base_link,
tip_link), validated like the command line's options, and each job's warnings reported
once by the coordinator (never as Python warnings on a worker's stderr)."""

from __future__ import annotations

import csv
import json
import warnings
from concurrent.futures import ThreadPoolExecutor
from importlib import resources

import numpy as np
import pytest

from kinecal.batch import parse_jobs, run_batch, run_job
from kinecal.batch.records import JobRecord
from kinecal.cli import main
from kinecal.cli.batch import MAX_PRINTED_ROWS, _print_warnings
from kinecal.errors import InputError
from kinecal.io.models import load_model

URDF = str(resources.files("rtbdata") / "xacro" / "abb_irb140_description/urdf/irb140.urdf")
BASE = {"name": "j", "model": "irb120", "poses": 20}


@pytest.mark.parametrize("keys, words", [
    ({"error_model": "bogus"}, "job j: error_model: unknown error model 'bogus'"),
    ({"folds": 5}, "job j: folds: cross-validation folds apply to --error-model auto"),
    ({"error_model": "compliance", "harmonics": 2}, "job j: harmonics: a harmonic order"),
    ({"error_model": "auto", "harmonics": 40}, "job j: harmonics: expected a harmonic order"),
    ({"error_model": "auto", "method": "pso"}, "error_model: error model auto needs a "
                                              "least-squares method"),
    ({"folds": 1, "error_model": "auto"}, "folds"),
    ({"base_link": "base_link"}, "job j: base_link: base_link and tip_link apply to URDF"),
    ({"model": URDF, "tip_link": "nope"}, "job j: tip_link: no link 'nope'"),
    ({"noise": 1e300}, "job j: noise: a noise standard deviation of 1e+300 mm is larger "
                       "than the whole machine"),
    ({"sigma": 5000.0}, "job j: sigma: a stated noise of 5000 mm is larger"),
    ({"sigma": 0.0}, "sigma"),
])
def test_bad_keys_are_refused_before_any_job(keys, words):
    with pytest.raises(InputError, match=r"jobs\.yaml") as err:
        parse_jobs({"jobs": [{**BASE, **keys}]}, ".", "jobs.yaml")
    assert words in str(err.value)


def test_error_model_job_equals_the_command_line(tmp_path, capsys):
    job = parse_jobs({"jobs": [{"name": "em", "model": "ur5", "data": "ur5-laser-tracker:grid",
                                "error_model": "auto", "folds": 4, "harmonics": 1,
                                "sigma": 0.02}]})[0]
    out = run_job(job)
    assert out["status"] == "done", out["error"]
    res = out["result"]
    assert res["error_model"]["folds"] == 4 and res["noise"]["stated_sigma"] == 0.02
    cli = tmp_path / "cli.json"
    assert main(["calibrate", "ur5", "ur5-laser-tracker:grid", "--error-model", "auto",
                 "--folds", "4", "--harmonics", "1", "--sigma", "0.02", "--out", str(cli),
                 "--quiet"]) == 0
    capsys.readouterr()
    ref = json.loads(cli.read_text())
    assert res["parameters"] == ref["parameters"]
    assert res["error_model"]["selected"] == ref["error_model"]["selected"]
    assert res["warnings"] == ref["warnings"] == out["warnings"]


def test_urdf_job_with_chain_ends():
    job = parse_jobs({"jobs": [{"name": "u", "model": URDF, "base_link": "base_link",
                                "tip_link": "link_6", "poses": 40, "noise": 0.0001}]})[0]
    out = run_job(job)
    assert out["status"] == "done", out["error"]
    model = load_model(URDF, base_link="base_link", tip_link="link_6")
    assert set(out["result"]["parameters"]) == set(model.parameter_names)
    assert out["result"]["job"]["tip_link"] == "link_6"
    # keys not given are left out of the recorded specification (older results resume)
    plain = parse_jobs({"jobs": [{"name": "p", "model": "irb120", "poses": 5}]})[0].spec()
    assert not {"error_model", "sigma", "base_link"} & set(plain) and "maxiter" in plain
    assert out["result"]["validation"] is None and out["result"]["calibration"]["n"] == 40


def test_job_warnings_are_collected_not_issued(tmp_path):
    """A job that warns (few poses; a stated noise below the simulated one): no Python
    warning, the codes in the record, the summary and the result JSON."""
    jobs = parse_jobs({"jobs": [
        {"name": "few", "model": "irb120", "poses": 12, "noise": 0.01},
        {"name": "noisy", "model": "irb120", "poses": 40, "noise": 0.02, "sigma": 0.005},
        {"name": "clean", "model": "irb120", "poses": 40, "noise": 0.01, "sigma": 0.01},
    ]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any Python warning fails the test
        with ThreadPoolExecutor(2) as ex:
            out = run_batch(jobs, tmp_path / "out", executor=ex)
    codes = {r.name: [w["code"] for w in r.warnings] for r in out.records}
    assert codes == {"few": ["few-poses"], "noisy": ["residual-above-noise"], "clean": []}
    with open(out.summary_path, newline="", encoding="utf-8") as fh:
        rows = {r["name"]: r["warnings"] for r in csv.DictReader(fh)}
    assert rows == {"few": "few-poses", "noisy": "residual-above-noise", "clean": ""}
    stored = json.loads((tmp_path / "out" / "noisy.json").read_text())
    assert [w["code"] for w in stored["warnings"]] == ["residual-above-noise"]


def test_cli_prints_each_jobs_warnings_once(tmp_path, capfd):
    (tmp_path / "jobs.yaml").write_text(
        "jobs:\n  - {name: few, model: irb120, poses: 12, noise: 0.01}\n"
        "  - {name: ok, model: irb120, poses: 40, noise: 0.01}\n", encoding="utf-8")
    args = ["batch", str(tmp_path / "jobs.yaml"), "--out", str(tmp_path / "out"),
            "--workers", "1", "--quiet"]
    assert main(args) == 0
    err = capfd.readouterr().err  # the worker processes' stderr as well
    lines = [ln for ln in err.splitlines() if "warning" in ln.lower()]
    assert len(lines) == 1 and lines[0].startswith("kinecal: warning: few: 12 distinct poses")
    assert lines[0].endswith("[few-poses]") and "KinecalWarning" not in err
    assert main(args) == 0  # resumed: the stored warnings are reported again, once
    lines = [ln for ln in capfd.readouterr().err.splitlines() if "warning" in ln]
    assert len(lines) == 1 and "few: " in lines[0]


def test_many_warned_jobs_are_grouped_by_code(capsys):
    records = []
    for k in range(MAX_PRINTED_ROWS + 5):
        rec = JobRecord(name=f"job{k}", method="lm", seed=k, noise=0.01, poses=10)
        rec.warnings = [{"code": "few-poses", "message": f"few {k}"}]
        records.append(rec)
    records[3].warnings.append({"code": "outliers", "message": "an outlier"})
    _print_warnings(records)
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2
    assert lines[0] == (f"kinecal: warning: {MAX_PRINTED_ROWS + 5} of {MAX_PRINTED_ROWS + 5} "
                        "jobs (codes per job in summary.csv); the first, job0: few 0 "
                        "[few-poses]")
    assert "1 of" in lines[1] and "job3: an outlier [outliers]" in lines[1]
    assert np.all([ln.startswith("kinecal: warning: ") for ln in lines])
