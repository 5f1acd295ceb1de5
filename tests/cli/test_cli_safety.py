"""Hostile arguments: inputs are never overwritten, every hole is exit 2 with one line.

Each case runs a command that must be refused before any work: exit status 2, exactly one
line on stderr naming the option or file, nothing on stdout, no output file created, and
every input file byte for byte as it was (its bytes and its modification time).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from kinecal.calibration.serial.simulate import simulate
from kinecal.cli import main
from kinecal.io.handeye import write_handeye_csv
from kinecal.io.measurements import write_measurements
from kinecal.io.models import load_model

ROBOTS = Path(__file__).resolve().parents[2] / "src" / "kinecal" / "robots"

#: a "billion laughs": 10 levels of 9 aliases each (about 10^9 nodes once expanded)
BOMB = "\n".join(
    ['a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    + [f"{chr(97 + i)}: &{chr(97 + i)} [" + ", ".join([f"*{chr(96 + i)}"] * 9) + "]"
       for i in range(1, 10)]) + "\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Good input files of every kind (the commands' targets), by name."""
    d = tmp_path_factory.mktemp("safety")
    model = load_model("irb120")
    sim = simulate(model, 30, noise=0.01, rng=1)
    write_measurements(d / "meas.csv", sim.data, model)
    write_measurements(d / "val.csv", simulate(model, 10, noise=0.01, rng=2).data, model)
    (d / "irb120.yaml").write_text((ROBOTS / "irb120.yaml").read_text(encoding="utf-8"),
                                   encoding="utf-8")
    (d / "cmm.yaml").write_text((ROBOTS / "liu2008-cmm.yaml").read_text(encoding="utf-8"),
                                encoding="utf-8")
    (d / "truth.json").write_text(json.dumps({"errors": {"d1": 0.1}}), encoding="utf-8")
    rng = np.random.default_rng(0)
    T = np.tile(np.eye(4), (6, 1, 1))
    T[:, :3, 3] = rng.normal(size=(6, 3))
    write_handeye_csv(d / "pairs.csv", T, T)
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "8",
                 "--out", str(d / "stewart.csv")]) == 0
    (d / "joints.csv").write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n", encoding="utf-8")
    for name, value in (("nan", "NaN"), ("inf", "Infinity"), ("bool", "true")):
        (d / f"{name}.json").write_text(f'{{"parameters": {{"d1": {{"identified": {value}}}}}}}',
                                        encoding="utf-8")
    (d / "bomb.yaml").write_text(BOMB, encoding="utf-8")
    (d / "bomb.yml").write_text(BOMB, encoding="utf-8")
    (d / "bombjobs.yaml").write_text(
        BOMB + "jobs: [{name: x, model: irb120, poses: 10, options: {x: *j}}]\n",
        encoding="utf-8")
    (d / "recursive.yaml").write_text("a: &a [*a]\n", encoding="utf-8")
    (d / "deep.yaml").write_text("a: " + "[" * 3000 + "]" * 3000 + "\n", encoding="utf-8")
    (d / "jobs.json").write_text(json.dumps({"jobs": [
        {"name": "jobs", "model": "irb120", "data": "meas.csv"}]}), encoding="utf-8")
    (d / "summary.csv").write_text((d / "meas.csv").read_text(encoding="utf-8"),
                                   encoding="utf-8")
    jobs = {
        "jobs_summary.yaml": "jobs: [{name: a, model: irb120, data: summary.csv}]\n",
        "jobs_case.yaml": "jobs: [{name: Arm, model: irb120, poses: 10},\n"
                          "       {name: arm, model: irb120, poses: 10}]\n",
        "jobs_huge.yaml": "jobs: [{name: a, model: irb120, poses: 2000000000}]\n",
        "jobs_inf.yaml": "jobs: [{name: a, model: irb120, poses: 10, noise: .inf}]\n",
        "jobs_loss.yaml": "jobs: [{name: a, model: irb120, poses: 10, method: pso, "
                          "loss: huber}]\n",
        "jobs_target.yaml": "study: {model: irb120, methods: [pso, lm], poses: [10], "
                            "target: 0.1}\n",
        "jobs_ok.yaml": "jobs: [{name: a, model: irb120, poses: 10}]\n",
    }
    for name, text in jobs.items():
        (d / name).write_text(text, encoding="utf-8")
    (d / "link.csv").symlink_to(d / "meas.csv")
    (d / "sub").mkdir()
    return d


def _snapshot(d: Path) -> dict[str, tuple[bytes, int]]:
    out = {}
    for p in sorted(d.rglob("*")):
        if p.is_file() and not p.is_symlink():
            out[str(p.relative_to(d))] = (p.read_bytes(), p.stat().st_mtime_ns)
    return out


LONG = "a" * 300 + ".csv"
BIG = "2000000000"

# (id, argv with {d} for the folder of the input files, text the message must contain)
CASES = [
    # item 3: an output equal to an input, or two outputs on one path
    ("calibrate-out-is-data", ["calibrate", "irb120", "{d}/meas.csv", "--out", "{d}/meas.csv"],
     "also the input DATA"),
    ("calibrate-out-is-data-via-link", ["calibrate", "irb120", "{d}/meas.csv", "--out",
                                        "{d}/link.csv"], "also the input DATA"),
    ("calibrate-out-is-data-dotted", ["calibrate", "irb120", "{d}/meas.csv", "--out",
                                      "{d}/sub/../meas.csv"], "also the input DATA"),
    ("calibrate-model-out-is-model", ["calibrate", "{d}/irb120.yaml", "{d}/meas.csv",
                                      "--model-out", "{d}/irb120.yaml"], "also the input MODEL"),
    ("calibrate-report-is-validate", ["calibrate", "irb120", "{d}/meas.csv", "--validate",
                                      "{d}/val.csv", "--report", "{d}/val.csv"],
     "also the input --validate"),
    ("calibrate-two-outputs", ["calibrate", "irb120", "{d}/meas.csv", "--out", "{d}/r.json",
                               "--report", "{d}/r.json"], "also given to --out"),
    ("simulate-out-is-model", ["simulate", "{d}/irb120.yaml", "--poses", "5", "--out",
                               "{d}/irb120.yaml"], "also the input MODEL"),
    ("simulate-truth-out-is-out", ["simulate", "irb120", "--poses", "5", "--out",
                                   "{d}/s.csv", "--truth-out", "{d}/s.csv"],
     "also given to --out"),
    ("simulate-out-is-errors", ["simulate", "irb120", "--poses", "5", "--errors",
                                "{d}/truth.json", "--out", "{d}/truth.json"],
     "also the input --errors"),
    ("select-poses-out-is-model", ["select-poses", "{d}/irb120.yaml", "--count", "5",
                                   "--out", "{d}/irb120.yaml"], "also the input MODEL"),
    ("handeye-out-is-pairs", ["handeye", "{d}/pairs.csv", "--out", "{d}/pairs.csv"],
     "also the input PAIRS"),
    ("handeye-two-outputs", ["handeye", "handeye-camodocal", "--out", "{d}/h.json",
                             "--report", "{d}/h.json"], "also given to --out"),
    ("stewart-simulate-two-outputs", ["stewart", "simulate", "liu2008-cmm", "--poses", "5",
                                      "--out", "{d}/x.csv", "--truth-out", "{d}/x.csv"],
     "also given to --out"),
    ("stewart-simulate-truth-is-errors", ["stewart", "simulate", "liu2008-cmm", "--errors",
                                          "{d}/cmm.yaml", "--out", "{d}/x.csv",
                                          "--truth-out", "{d}/cmm.yaml"],
     "also the input --errors"),
    ("stewart-calibrate-out-is-data", ["stewart", "calibrate", "liu2008-cmm",
                                       "{d}/stewart.csv", "--out", "{d}/stewart.csv"],
     "also the input DATA"),
    ("stewart-calibrate-geometry-out-is-geometry", ["stewart", "calibrate", "{d}/cmm.yaml",
                                                   "{d}/stewart.csv", "--geometry-out",
                                                   "{d}/cmm.yaml"], "also the input GEOMETRY"),
    ("reproduce-report-is-result", ["reproduce", "liu2008", "--quick", "--out", "{d}/rep",
                                    "--report", "{d}/rep/result.json"], "also given to"),
    ("compensate-out-is-program", ["compensate", "{d}/irb120.yaml", "{d}/joints.csv", "--out",
                                   "{d}/joints.csv"], "also the input PROGRAM"),
    ("export-out-is-source", ["export", "{d}/irb120.yaml", "--format", "yaml", "--out",
                              "{d}/irb120.yaml"], "also the input SOURCE"),
    ("batch-result-on-jobs-file", ["batch", "{d}/jobs.json", "--out", "{d}"],
     "is the jobs file"),
    ("batch-summary-on-data", ["batch", "{d}/jobs_summary.yaml", "--out", "{d}"],
     "is the data file of job a"),
    ("batch-names-differ-in-case", ["batch", "{d}/jobs_case.yaml", "--out", "{d}/b"],
     "differ only in case"),
    # files given where folders are expected, and the other way round
    ("calibrate-data-is-a-folder", ["calibrate", "irb120", "{d}/sub"],
     "is a directory, expected a CSV"),
    ("model-is-a-folder", ["fk", "{d}/sub", "{d}/joints.csv"], "is a directory"),
    ("geometry-is-a-folder", ["stewart", "fk", "{d}/sub", "{d}/joints.csv"],
     "is a directory"),
    ("jobs-file-is-a-folder", ["batch", "{d}/sub", "--out", "{d}/b"], "is a directory"),
    ("out-file-is-a-folder", ["simulate", "irb120", "--poses", "5", "--out", "{d}/sub"],
     "is a directory"),
    ("batch-out-is-a-file", ["batch", "{d}/jobs_ok.yaml", "--out", "{d}/meas.csv"],
     "is a file, expected a directory"),
    ("reproduce-out-is-a-file", ["reproduce", "liu2008", "--out", "{d}/meas.csv"],
     "is a file, expected a directory"),
    ("demo-out-is-a-file", ["demo", "--out", "{d}/meas.csv"], "is a file, expected a directory"),
    ("out-in-a-missing-folder", ["simulate", "irb120", "--poses", "5", "--out",
                                 "{d}/nowhere/s.csv"], "does not exist"),
    ("out-name-too-long", ["simulate", "irb120", "--poses", "5", "--out", "{d}/" + LONG],
     "file name too long"),
    # item 4: negative seeds (refused everywhere: an integer >= 0)
    ("simulate-negative-seed", ["simulate", "irb120", "--poses", "5", "--seed", "-1",
                                "--out", "{d}/s.csv"], "--seed"),
    ("calibrate-negative-seed", ["calibrate", "irb120", "{d}/meas.csv", "--seed", "-1"],
     "--seed"),
    ("identifiability-negative-seed", ["identifiability", "irb120", "--seed", "-1"], "--seed"),
    ("select-poses-negative-seed", ["select-poses", "irb120", "--count", "5", "--seed", "-1",
                                    "--out", "{d}/s.csv"], "--seed"),
    ("handeye-negative-seed", ["handeye", "handeye-camodocal", "--refine", "igwo", "--seed",
                               "-1"], "--seed"),
    ("handeye-poses-negative-seed", ["handeye-poses", "--distance", "500", "--radius", "100",
                                     "--count", "8", "--scheme", "random", "--seed", "-1",
                                     "--out", "{d}/p.csv"], "--seed"),
    ("stewart-fk-negative-seed", ["stewart", "fk", "liu2008-cmm", "{d}/stewart.csv",
                                  "--method", "pso", "--seed", "-1"], "--seed"),
    ("stewart-simulate-negative-seed", ["stewart", "simulate", "liu2008-cmm", "--seed", "-1",
                                        "--out", "{d}/x.csv"], "--seed"),
    ("reproduce-negative-seed", ["reproduce", "liu2008", "--quick", "--seed", "-1"], "--seed"),
    # non-finite or non-positive numbers
    ("simulate-infinite-noise", ["simulate", "irb120", "--poses", "5", "--noise", "inf",
                                 "--out", "{d}/s.csv"], "option --noise: expected a finite"),
    ("simulate-infinite-angle-noise", ["simulate", "irb120", "--poses", "5", "--orientation",
                                       "--angle-noise", "inf", "--out", "{d}/s.csv"],
     "option --angle-noise"),
    ("calibrate-infinite-target", ["calibrate", "irb120", "{d}/meas.csv", "--method", "pso",
                                   "--target", "inf"], "option --target"),
    ("calibrate-negative-target", ["calibrate", "irb120", "{d}/meas.csv", "--method", "pso",
                                   "--target", "-1"], "option --target"),
    ("calibrate-zero-rotation-weight", ["calibrate", "irb120", "{d}/meas.csv",
                                        "--rotation-weight", "0"], "option --rotation-weight"),
    ("calibrate-nan-rotation-weight", ["calibrate", "irb120", "{d}/meas.csv",
                                       "--rotation-weight", "nan"], "option --rotation-weight"),
    ("handeye-poses-overflow", ["handeye-poses", "--distance", "500", "--radius", "1e300",
                                "--count", "8", "--out", "{d}/p.csv"], "overflow"),
    ("batch-infinite-noise", ["batch", "{d}/jobs_inf.yaml", "--out", "{d}/b"],
     "finite number"),
    # NaN (or no number) in a result given to fk --params
    ("fk-params-nan", ["fk", "irb120", "{d}/joints.csv", "--params", "{d}/nan.json"],
     "expected a finite number"),
    ("fk-params-infinity", ["fk", "irb120", "{d}/joints.csv", "--params", "{d}/inf.json"],
     "expected a finite number"),
    ("fk-params-boolean", ["fk", "irb120", "{d}/joints.csv", "--params", "{d}/bool.json"],
     "expected a finite number"),
    ("fk-params-is-a-device", ["fk", "irb120", "{d}/joints.csv", "--params", "/dev/zero"],
     "is a device"),
    ("jobs-file-is-a-device", ["batch", "/dev/zero", "--out", "{d}/b"], "is a device"),
    # YAML alias bombs, recursive aliases, nesting beyond the recursion limit
    ("model-alias-bomb", ["calibrate", "{d}/bomb.yaml", "{d}/meas.csv"], "alias bomb"),
    ("jobs-alias-bomb", ["batch", "{d}/bombjobs.yaml", "--out", "{d}/b"], "alias bomb"),
    ("handeye-alias-bomb", ["handeye", "{d}/bomb.yml"], "alias bomb"),
    ("geometry-alias-bomb", ["stewart", "fk", "{d}/bomb.yaml", "{d}/stewart.csv"],
     "alias bomb"),
    ("model-recursive-alias", ["fk", "{d}/recursive.yaml", "{d}/joints.csv"],
     "refers to itself"),
    ("model-deep-nesting", ["fk", "{d}/deep.yaml", "{d}/joints.csv"], "nested too deeply"),
    # absurd sizes, refused before allocating
    ("simulate-huge-poses", ["simulate", "irb120", "--poses", BIG, "--out", "{d}/s.csv"],
     "GB of memory"),
    ("identifiability-huge-poses", ["identifiability", "irb120", "--poses", BIG],
     "GB of memory"),
    ("select-poses-huge-candidates", ["select-poses", "irb120", "--count", "5",
                                      "--candidates", BIG, "--out", "{d}/s.csv"],
     "GB of memory"),
    ("handeye-poses-huge-count", ["handeye-poses", "--distance", "500", "--radius", "100",
                                  "--count", BIG, "--out", "{d}/p.csv"], "GB of memory"),
    ("stewart-simulate-huge-poses", ["stewart", "simulate", "liu2008-cmm", "--poses", BIG,
                                     "--out", "{d}/x.csv"], "GB of memory"),
    ("batch-huge-poses", ["batch", "{d}/jobs_huge.yaml", "--out", "{d}/b"], "GB of memory"),
    ("select-poses-negative-candidates", ["select-poses", "irb120", "--count", "5",
                                          "--candidates", "-5", "--out", "{d}/s.csv"],
     "option --candidates"),
    ("stewart-simulate-negative-poses", ["stewart", "simulate", "liu2008-cmm", "--poses",
                                         "-3", "--out", "{d}/x.csv"], "option --poses"),
    # options that the chosen method would silently ignore
    ("loss-with-metaheuristic", ["calibrate", "irb120", "{d}/meas.csv", "--method", "pso",
                                 "--loss", "huber"], "applies to method lm only"),
    ("loss-with-householder", ["calibrate", "irb120", "{d}/meas.csv", "--method",
                               "householder", "--loss", "cauchy"], "option --loss"),
    ("target-with-lm", ["calibrate", "irb120", "{d}/meas.csv", "--target", "0.1"],
     "option --target"),
    ("target-with-householder", ["calibrate", "irb120", "{d}/meas.csv", "--method",
                                 "householder", "--target", "0.1"], "option --target"),
    ("maxiter-with-lm", ["calibrate", "irb120", "{d}/meas.csv", "--maxiter", "5"],
     "option --maxiter"),
    ("rotation-weight-without-orientations", ["calibrate", "irb120", "{d}/meas.csv",
                                              "--rotation-weight", "100"],
     "measured orientations"),
    ("identifiability-poses-with-data", ["identifiability", "irb120", "--data",
                                         "{d}/meas.csv", "--poses", "10"], "option --poses"),
    ("identifiability-seed-with-data", ["identifiability", "irb120", "--data",
                                        "{d}/meas.csv", "--seed", "3"], "option --seed"),
    ("handeye-pairs-with-axzb", ["handeye", "handeye-camodocal", "--method", "li", "--pairs",
                                 "consecutive"], "option --pairs"),
    ("stewart-fk-all-with-pso", ["stewart", "fk", "liu2008-cmm", "{d}/stewart.csv", "--all",
                                 "--method", "pso"], "option --method"),
    ("harmonics-without-harmonic-model", ["calibrate", "irb120", "{d}/meas.csv",
                                          "--harmonics", "3"], "option --harmonics"),
    ("harmonics-with-compliance", ["calibrate", "irb120", "{d}/meas.csv", "--error-model",
                                   "compliance", "--harmonics", "3"], "option --harmonics"),
    ("folds-without-auto", ["calibrate", "irb120", "{d}/meas.csv", "--error-model",
                            "harmonic", "--folds", "5"], "option --folds"),
    ("batch-too-many-workers", ["batch", "{d}/jobs_ok.yaml", "--out", "{d}/b", "--workers",
                                "100000"], "option --workers"),
    ("batch-workers-with-scheduler", ["batch", "{d}/jobs_ok.yaml", "--out", "{d}/b",
                                      "--executor", "dask", "--scheduler",
                                      "tcp://127.0.0.1:1", "--workers", "2"],
     "option --workers"),
    ("batch-loss-with-metaheuristic", ["batch", "{d}/jobs_loss.yaml", "--out", "{d}/b"],
     "job a: loss"),
    ("batch-target-with-lm", ["batch", "{d}/jobs_target.yaml", "--out", "{d}/b"],
     "target: a target mean error"),
]


@pytest.mark.parametrize(("argv", "expected"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_refused_before_any_work(argv, expected, files, capsys):
    before = _snapshot(files)
    code = main([a.replace("{d}", str(files)) for a in argv])
    out, err = capsys.readouterr()
    assert code == 2, err
    assert err.startswith("kinecal: error: ") and err.count("\n") == 1, err
    assert expected in err, err
    assert out == ""
    assert _snapshot(files) == before  # nothing written, every input untouched
    assert not (files / "b").exists() and not (files / "rep").exists()


def test_every_writing_command_is_covered():
    """Every command that writes files has at least one collision case above."""
    covered = {c[1][0] if c[1][0] != "stewart" else "stewart " + c[1][1] for c in CASES
               if "also" in c[2] or "jobs file" in c[2] or "data file" in c[2]}
    assert {"calibrate", "simulate", "select-poses", "handeye", "stewart simulate",
            "stewart calibrate", "reproduce", "batch", "compensate", "export"} <= covered


def test_output_through_a_link_to_a_device_is_written_in_place(tmp_path, capsys):
    """``--out`` naming a device (here through a link to /dev/null) writes into it: the
    device is never replaced by a regular file, and the link stays a link."""
    link = tmp_path / "discard.csv"
    link.symlink_to("/dev/null")
    assert main(["simulate", "irb120", "--poses", "5", "--out", str(link)]) == 0
    assert link.is_symlink() and os.readlink(link) == "/dev/null"
    assert Path("/dev/null").is_char_device()
    assert [p.name for p in tmp_path.iterdir()] == ["discard.csv"]  # no temp file left
    capsys.readouterr()


def test_output_into_a_fifo_streams_the_data(tmp_path, capsys):
    import threading

    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_text(encoding="utf-8")))
    reader.start()
    assert main(["simulate", "irb120", "--poses", "3", "--out", str(fifo)]) == 0
    reader.join(10)
    assert got and got[0].startswith("q1,q2,q3,q4,q5,q6,x,y,z\n") and got[0].count("\n") == 4
    assert fifo.is_fifo()
    capsys.readouterr()


def test_read_only_output_is_refused(tmp_path, capsys, monkeypatch):
    """An existing output without write permission is not replaced (tests may run as
    root, who may write anything: the permission test is simulated)."""
    out = tmp_path / "keep.csv"
    out.write_text("precious\n", encoding="utf-8")
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False
                        if Path(p) == out and mode == os.W_OK else real(p, mode, **kw))
    code = main(["simulate", "irb120", "--poses", "3", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "read-only" in err and err.count("\n") == 1
    assert out.read_text(encoding="utf-8") == "precious\n"


def test_read_only_folder_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, **kw: False
                        if Path(p) == tmp_path and mode & os.W_OK else real(p, mode, **kw))
    code = main(["calibrate", "irb120", "ur5-laser-tracker:random", "--out",
                 str(tmp_path / "r.json")])
    err = capsys.readouterr().err
    assert code == 2 and "is not writable" in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_a_long_but_valid_output_name_is_written(tmp_path, capsys):
    """250 bytes is a valid name: the temporary name beside it must not be too long."""
    out = tmp_path / ("b" * 246 + ".csv")
    assert main(["simulate", "irb120", "--poses", "3", "--out", str(out)]) == 0
    assert out.read_text(encoding="utf-8").startswith("q1,")
    capsys.readouterr()


def test_identifiability_defaults_still_apply(capsys):
    """--poses and --seed default to 50 and 0 without --data (they are only refused with it)."""
    assert main(["identifiability", "irb120", "--json"]) == 0
    a = json.loads(capsys.readouterr().out)
    assert main(["identifiability", "irb120", "--json", "--poses", "50", "--seed", "0"]) == 0
    assert json.loads(capsys.readouterr().out) == a


def test_bundled_inputs_are_protected_like_files():
    """A bundled model, geometry, dataset or hand-eye recording given by name is the file
    inside the package: an output onto it is refused (checked without running a command,
    so that a regression could not overwrite the package's own data)."""
    from kinecal.cli._common import check_paths
    from kinecal.datasets import bundled_csv
    from kinecal.errors import InputError
    from kinecal.io.bundled import robots_dir

    cases = [("MODEL", "irb120", robots_dir() / "irb120.yaml"),
             ("GEOMETRY", "liu2008-cmm", robots_dir() / "liu2008-cmm.yaml"),
             ("DATA", "ur5-laser-tracker:grid", bundled_csv("ur5-laser-tracker:grid")),
             ("PAIRS", "handeye-camodocal", bundled_csv("handeye-camodocal:pairs"))]
    for name, spec, path in cases:
        with pytest.raises(InputError, match=f"also the input {name}"):
            check_paths({name: spec}, {"--out": path})


def test_options_the_hand_eye_refiner_would_ignore_are_refused():
    from kinecal.calibration.handeye import calibrate_handeye
    from kinecal.datasets import bundled_csv
    from kinecal.errors import InputError
    from kinecal.io.handeye import read_handeye_pairs

    F, C = read_handeye_pairs(bundled_csv("handeye-camodocal:pairs"))
    for refine, kwargs, words in [("none", {"rotation_weight": 100.0}, "refine lm"),
                                  ("igwo", {"robust": False}, "refine lm"),
                                  ("lm", {"options": {"popsize": 10}}, "metaheuristic")]:
        with pytest.raises(InputError, match=words):
            calibrate_handeye(F, C, setup="eye-to-hand", refine=refine, **kwargs)
