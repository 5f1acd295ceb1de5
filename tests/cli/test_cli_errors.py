"""The CLI error contract (DESIGN sec. 4): every user mistake exits 2 with exactly one line
on stderr naming the file, row or option, no traceback, nothing on stdout and nothing
half-written."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from kinecal.cli import main

ROBOTS = Path(__file__).resolve().parents[2] / "src" / "kinecal" / "robots"
PAIRS_YML = (Path(__file__).resolve().parents[2] / "src" / "kinecal" / "datasets"
             / "handeye-camodocal" / "TransformPairsInput.yml")
HEADER = "q1,q2,q3,q4,q5,q6,x,y,z"


def _good_csv(n=30):
    rows = [f"{i},{2 * i},{3 * i},{i},{i},{i},{100 + i},{200 + i},{300 + i}"
            for i in range(1, n + 1)]
    return HEADER + "\n" + "\n".join(rows) + "\n"


def _handeye_csv(rows):
    cols = [f"{p}_{c}" for p in ("flange", "target") for c in ("x", "y", "z", "qw", "qx", "qy",
                                                                  "qz")]
    return ",".join(cols) + "\n" + "\n".join(",".join(f"{v:.9f}" for v in r)
                                             for r in rows) + "\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Malformed (and a few good) input files, by name."""
    d = tmp_path_factory.mktemp("bad-inputs")
    good = _good_csv()
    ur5 = (ROBOTS / "ur5.yaml").read_text(encoding="utf-8")
    pairs = PAIRS_YML.read_text(encoding="utf-8")
    rng = np.random.default_rng(0)
    he_rows = []
    for _ in range(8):
        q1, q2 = rng.normal(size=4), rng.normal(size=4)
        he_rows.append([*rng.normal(size=3), *(q1 / np.linalg.norm(q1)), *rng.normal(size=3),
                        *(q2 / np.linalg.norm(q2))])
    non_unit = [r[:] for r in he_rows]
    non_unit[3][3] = 2.0
    texts = {
        "good.csv": good,
        "missing_column.csv": "q1,q2,q3,q4,q5,q6,x,y\n" + "1,2,3,4,5,6,7,8\n" * 30,
        "nan.csv": good.replace("101,201", "nan,201"),
        "text_cell.csv": good.replace("103,203", "abc,203"),
        "short_row.csv": good.replace(",105,205,305", ",105,205"),
        "seven_joints.csv": "q1,q2,q3,q4,q5,q6,q7,x,y,z\n" + "1,2,3,4,5,6,7,8,9,10\n" * 30,
        "five_joints.csv": "q1,q2,q3,q4,q5,x,y,z\n" + "1,2,3,4,5,6,7,8\n" * 30,
        "empty.csv": "",
        "header_only.csv": HEADER + "\n",
        "two_poses.csv": HEADER + "\n1,2,3,4,5,6,7,8,9\n2,3,4,5,6,7,8,9,1\n",
        "negative_weight.csv": HEADER + ",weight\n" + "1,2,3,4,5,6,7,8,9,-1\n" * 30,
        "binary.csv": "\x00\x01\x02garbage",
        "unclosed.yaml": "name: [unclosed\n  - {",
        "list.yaml": "- 1\n- 2\n",
        "grad.yaml": ur5.replace("angle_unit: deg", "angle_unit: grad"),
        "furlong.yaml": ur5.replace("length_unit: mm", "length_unit: furlong"),
        "convention.yaml": ur5.replace("convention: dh", "convention: denavit"),
        "joint_no_a.yaml": ur5.replace("{theta: 0, d: 89.159, a: 0, alpha: 90}",
                                       "{theta: 0, d: 89.159, alpha: 90}"),
        "short_base.yaml": ur5.replace("base: [0, 0, 0, 0, 0, 0]", "base: [0, 0, 0]"),
        "fk_missing.csv": "q1,q2\n1,2\n",
        "fk_good.csv": "q1,q2,q3,q4,q5,q6\n1,2,3,4,5,6\n",
        "broken.json": "{not json",
        "other_model.json": '{"parameters": {"zz1": {"identified": 1}}}',
        "truth_no_errors.json": '{"a": 1}',
        "he_missing.csv": "flange_x,flange_y\n1,2\n",
        "he_non_unit.csv": _handeye_csv(non_unit),
        "he_two.csv": _handeye_csv(he_rows[:2]),
        "he_non_orthonormal.yml": pairs.replace("6.3848318753984534e-01", "1.5", 1),
        "he_3x4.yml": pairs.replace("rows: 4\n   cols: 4\n   dt: d\n   data: [ "
                                    "6.3848318753984534e-01,",
                                    "rows: 3\n   cols: 4\n   dt: d\n   data: [", 1),
        "he.txt": "x",
        "legs5.csv": "l1,l2,l3,l4,l5\n0.8,0.8,0.8,0.8,0.8\n",
        "legs_unreachable.csv": "l1,l2,l3,l4,l5,l6\n5,0.1,0.8,0.8,0.8,0.8\n",
        "legs_nan.csv": "l1,l2,l3,l4,l5,l6\nnan,0.8,0.8,0.8,0.8,0.8\n",
        "legs.csv": "l1,l2,l3,l4,l5,l6\n0.8,0.8,0.8,0.8,0.8,0.8\n",
        "stewart_poses_xy.csv": "x,y\n1,2\n",
        "geometry_no_range.yaml": "base_radius: 0.5\n",
        "jobs_unclosed.yaml": "jobs: [\n",
    }
    out = {}
    for name, text in texts.items():
        (d / name).write_text(text, encoding="utf-8")
        out[name] = str(d / name)
    out["dir"] = str(d)
    return out


# (id, argv with {file} placeholders, text the one-line message must contain)
CASES = [
    ("missing-column", ["calibrate", "ur5", "{missing_column.csv}"], "missing column(s) z"),
    ("nan", ["calibrate", "ur5", "{nan.csv}"], "row 1: column x"),
    ("not-a-number", ["calibrate", "ur5", "{text_cell.csv}"], "row 3"),
    ("short-row", ["calibrate", "ur5", "{short_row.csv}"], "row 5"),
    ("seven-joints", ["calibrate", "ur5", "{seven_joints.csv}"], "6 joints"),
    ("five-joints", ["identifiability", "ur5", "--data", "{five_joints.csv}"], "6 joints"),
    ("empty-file", ["calibrate", "ur5", "{empty.csv}"], "empty file"),
    ("header-only", ["calibrate", "ur5", "{header_only.csv}"], "0 data rows"),
    ("too-few-poses", ["calibrate", "ur5", "{two_poses.csv}", "--free", "all"],
     "[too-few-poses]"),
    ("negative-weight", ["calibrate", "ur5", "{negative_weight.csv}"], "column weight"),
    ("binary-csv", ["calibrate", "ur5", "{binary.csv}"], "missing column(s)"),
    ("missing-file", ["calibrate", "ur5", "{dir}/nope.csv"], "file not found"),
    ("directory-as-csv", ["calibrate", "ur5", "{dir}"], "is a directory, expected a CSV"),
    ("unknown-model", ["calibrate", "ur6", "ur5-laser-tracker:grid"], "unknown model 'ur6'"),
    ("unknown-dataset-part", ["calibrate", "ur5", "ur5-laser-tracker:grd"], "no part 'grd'"),
    ("unknown-dataset", ["fk", "ur5", "nosuch:grid"], "bundled dataset"),
    ("unreadable-yaml", ["calibrate", "{unclosed.yaml}", "ur5-laser-tracker:random"],
     "not valid YAML"),
    ("yaml-not-mapping", ["fk", "{list.yaml}", "{fk_good.csv}"], "YAML mapping"),
    ("wrong-angle-unit", ["calibrate", "{grad.yaml}", "ur5-laser-tracker:random"],
     "angle_unit"),
    ("wrong-length-unit", ["simulate", "{furlong.yaml}", "--poses", "5", "--out",
                           "{dir}/s.csv"], "length_unit"),
    ("unknown-convention", ["identifiability", "{convention.yaml}"], "convention"),
    ("joint-without-a", ["calibrate", "{joint_no_a.yaml}", "ur5-laser-tracker:random"],
     "joints.0.a"),
    ("base-three-values", ["calibrate", "{short_base.yaml}", "ur5-laser-tracker:random"],
     "expected 6 values"),
    ("unknown-method", ["calibrate", "ur5", "ur5-laser-tracker:random", "--method",
                        "newton"], "option --method"),
    ("unknown-loss", ["calibrate", "ur5", "ur5-laser-tracker:random", "--loss", "l3"],
     "option --loss"),
    ("unknown-free-name", ["calibrate", "ur5", "ur5-laser-tracker:random", "--free",
                           "d1,zz"], "option --free"),
    ("empty-free-list", ["calibrate", "ur5", "ur5-laser-tracker:random", "--free", ","],
     "option --free"),
    ("maxiter-zero", ["calibrate", "ur5", "ur5-laser-tracker:random", "--maxiter", "0"],
     "option --maxiter"),
    ("maxiter-text", ["calibrate", "ur5", "ur5-laser-tracker:random", "--maxiter", "ten"],
     "--maxiter"),
    ("unknown-option", ["calibrate", "ur5", "ur5-laser-tracker:random", "--frobnicate"],
     "--frobnicate"),
    ("validate-wrong-joints", ["calibrate", "ur5", "ur5-laser-tracker:random", "--validate",
                               "{seven_joints.csv}"], "seven_joints.csv"),
    ("output-under-a-file", ["calibrate", "ur5", "ur5-laser-tracker:grid",
                             "--out", "{good.csv}/r.json"], "cannot write"),
    ("report-is-a-directory", ["calibrate", "ur5", "ur5-laser-tracker:grid",
                               "--report", "{dir}"], "is a directory"),
    ("fk-missing-joints", ["fk", "ur5", "{fk_missing.csv}"], "missing column(s) q3"),
    ("fk-broken-params-json", ["fk", "ur5", "{fk_good.csv}", "--params", "{broken.json}"],
     "not valid JSON at line 1"),
    ("fk-params-of-another-model", ["fk", "ur5", "{fk_good.csv}", "--params",
                                    "{other_model.json}"], "does not belong"),
    ("simulate-zero-poses", ["simulate", "ur5", "--poses", "0", "--out", "{dir}/s.csv"],
     "option --poses"),
    ("simulate-negative-noise", ["simulate", "ur5", "--poses", "5", "--noise", "-1",
                                 "--out", "{dir}/s.csv"], "option --noise"),
    ("simulate-nan-noise", ["simulate", "ur5", "--poses", "5", "--noise", "nan", "--out",
                            "{dir}/s.csv"], "option --noise"),
    ("simulate-bad-truth", ["simulate", "ur5", "--poses", "5", "--errors",
                            "{truth_no_errors.json}", "--out", "{dir}/s.csv"],
     "'errors' mapping"),
    ("identifiability-zero-poses", ["identifiability", "ur5", "--poses", "0"],
     "option --poses"),
    ("handeye-missing-columns", ["handeye", "{he_missing.csv}"], "missing column(s)"),
    ("handeye-non-unit-quaternion", ["handeye", "{he_non_unit.csv}"], "row 4"),
    ("handeye-non-orthonormal-matrix", ["handeye", "{he_non_orthonormal.yml}"],
     "not orthonormal"),
    ("handeye-3x4-matrix", ["handeye", "{he_3x4.yml}"], "expected 4x4"),
    ("handeye-too-few-stations", ["handeye", "{he_two.csv}"], "at least 3"),
    ("handeye-file-type", ["handeye", "{he.txt}"], "unknown file type"),
    ("handeye-unknown-method", ["handeye", "handeye-camodocal", "--method", "magic"],
     "unknown method"),
    ("handeye-unknown-setup", ["handeye", "handeye-camodocal", "--setup", "eye-on-hand"],
     "unknown setup"),
    ("handeye-poses-count", ["handeye-poses", "--distance", "500", "--radius", "100",
                             "--count", "2", "--out", "{dir}/p.csv"], "at least 3"),
    ("handeye-poses-negative-radius", ["handeye-poses", "--distance", "500", "--radius",
                                       "-100", "--count", "8", "--out", "{dir}/p.csv"],
     "positive length"),
    ("stewart-unknown-geometry", ["stewart", "fk", "nogeom", "{legs.csv}"],
     "unknown geometry"),
    ("stewart-five-legs", ["stewart", "fk", "liu2008-cmm", "{legs5.csv}"],
     "missing column(s) l6"),
    ("stewart-unreachable-legs", ["stewart", "fk", "liu2008-cmm", "{legs_unreachable.csv}"],
     "leg range"),
    ("stewart-nan-legs", ["stewart", "fk", "liu2008-cmm", "{legs_nan.csv}"], "column l1"),
    ("stewart-unknown-method", ["stewart", "fk", "liu2008-cmm", "{legs.csv}", "--method",
                                "bfgs"], "option --method"),
    ("stewart-ik-missing-columns", ["stewart", "ik", "liu2008-cmm",
                                    "{stewart_poses_xy.csv}"], "missing column(s) z"),
    ("stewart-incomplete-geometry", ["stewart", "ik", "{geometry_no_range.yaml}",
                                     "{stewart_poses_xy.csv}"], "leg_range"),
    ("stewart-calibrate-legs-only", ["stewart", "calibrate", "liu2008-cmm", "{legs.csv}"],
     "missing column(s) x"),
    ("reproduce-unknown-paper", ["reproduce", "nopaper"], "unknown paper"),
    ("batch-unreadable-jobs", ["batch", "{jobs_unclosed.yaml}", "--out", "{dir}/b"],
     "not valid YAML"),
    ("demo-out-is-a-file", ["demo", "--out", "{good.csv}"], "expected a directory"),
    ("bench-unknown-script", ["bench", "--only", "zzz"], "unknown benchmark"),
]


def _argv(template, files):
    out = []
    for arg in template:
        for name, path in files.items():
            arg = arg.replace("{" + name + "}", path)
        out.append(arg)
    return out


@pytest.mark.parametrize(("argv", "expected"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_user_mistake_gives_exit_2_and_one_line(argv, expected, files, capsys):
    code = main(_argv(argv, files))
    out, err = capsys.readouterr()
    assert code == 2, err
    assert err.startswith("kinecal: error: ") and err.endswith("\n")
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    assert expected in err
    assert out == ""


def test_at_least_thirty_cases_over_every_command():
    assert len(CASES) >= 30
    commands = {c[1][0] for c in CASES}
    assert {"calibrate", "fk", "simulate", "identifiability", "handeye", "stewart"} <= commands


def test_internal_error_is_exit_1_and_one_line(files, capsys, monkeypatch):
    """A failure that is not the user's (here: the disk) is exit 1, still one line."""
    def disk_full(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", disk_full)
    code = main(["simulate", "ur5", "--poses", "5", "--out", files["dir"] + "/full.csv"])
    err = capsys.readouterr().err
    assert code == 1
    assert err.startswith("kinecal: error: ") and err.count("\n") == 1
    assert "full.csv: No space left on device" in err  # names the file, not a traceback
    assert not (Path(files["dir"]) / "full.csv").exists()


def test_a_bug_is_exit_1_and_one_line(capsys, monkeypatch):
    """An exception kinecal did not expect: exit 1, one line saying it is internal."""
    import kinecal.io.models

    def broken(*args, **kwargs):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(kinecal.io.models, "load_model", broken)
    code = main(["fk", "irb120", "ur5-laser-tracker:random"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1
    assert err.startswith("kinecal: internal error: ZeroDivisionError: boom")


def test_failed_write_leaves_existing_output_whole(tmp_path, capsys, monkeypatch):
    """An existing output is replaced whole or not at all: a write that fails midway (disk
    full at fsync) leaves the old file byte for byte and no temporary file behind."""
    out = tmp_path / "result.json"
    assert main(["calibrate", "ur5", "ur5-laser-tracker:random", "--free", "d1,a2",
                 "--out", str(out), "--quiet"]) == 0
    before = out.read_bytes()
    assert json.loads(before)["parameters"]["d1"]["free"] is True

    def disk_full(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", disk_full)
    code = main(["calibrate", "ur5", "ur5-laser-tracker:random", "--free", "d1,a2,a3",
                 "--out", str(out), "--quiet"])
    capsys.readouterr()
    assert code == 1
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]
    monkeypatch.undo()
    # and a user mistake (wrong joint count in the validation file) leaves it untouched
    bad = tmp_path / "val.csv"
    bad.write_text("q1,q2,q3,q4,q5,q6,q7,x,y,z\n" + "1,2,3,4,5,6,7,8,9,10\n" * 5,
                   encoding="utf-8")
    code = main(["calibrate", "ur5", "ur5-laser-tracker:random", "--free", "d1",
                 "--validate", str(bad), "--out", str(out)])
    assert code == 2
    assert out.read_bytes() == before
