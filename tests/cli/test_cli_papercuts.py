"""The newcomer's papercuts of issue 27: --version, --unit, choices and units in --help, one
"file not found", progress totals, the CSV separator named, select-poses feeding
identifiability and simulate, coverage only where it means something, ``| head``."""

from __future__ import annotations

import csv
import importlib.metadata
import io
import json
import re
import subprocess
import sys

import numpy as np
import pytest

import kinecal
from kinecal.cli import main
from kinecal.errors import InputError


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"kinecal {importlib.metadata.version('kinecal')}\n"
    assert kinecal.__version__ == importlib.metadata.version("kinecal")


# ---------------------------------------------------------------------------- --unit
def test_display_unit_rule():
    from kinecal.metrology.units import display_unit

    assert display_unit("m", None, [0.008, 2e-5]) == ("mm", 1000.0)
    assert display_unit("m", "auto", [1.5]) == ("m", 1.0)  # errors of metres: kept
    assert display_unit("mm", None, [3000.0]) == ("mm", 1.0)
    assert display_unit("m", "um", []) == ("um", 1e6)
    assert display_unit("mm", "m", []) == ("m", 1e-3)
    with pytest.raises(ValueError, match="unknown unit"):
        display_unit("mm", "in")
    with pytest.raises(ValueError, match="cannot show lengths of unit 'ft'"):
        display_unit("ft", "mm")


def _table(text: str) -> dict[str, list[float]]:
    rows = {}
    for line in text.splitlines():
        m = re.match(r"(cal|val)\. (before|after)\s+\d+\s+(.*)", line)
        if m and f"{m[1]} {m[2]}" not in rows:  # the position table comes first
            rows[f"{m[1]} {m[2]}"] = [float(v) for v in m[3].split()]
    return rows


def test_unit_of_a_model_in_metres(tmp_path, capsys):
    """A URDF-like model in metres: the summary in mm by default, in um or m on request,
    the same numbers scaled exactly; the JSON in metres, saying so."""
    from importlib import resources

    urdf = resources.files("kinecal") / "datasets" / "kr16-urdf" / "kr16_2.urdf"
    meas, out = tmp_path / "meas.csv", tmp_path / "r.json"
    assert main(["simulate", str(urdf), "--poses", "40", "--noise", "1e-5", "--seed", "1",
                 "--out", str(meas), "--quiet"]) == 0
    texts = {}
    for unit in ("auto", "um", "m"):
        assert main(["calibrate", str(urdf), str(meas), "--unit", unit, "--out",
                     str(out)]) == 0
        texts[unit] = capsys.readouterr().out
    assert "position error [mm]" in texts["auto"] and "position error [um]" in texts["um"]
    assert "position error [m]" in texts["m"]
    result = json.loads(out.read_text())
    assert result["length_unit"] == "m"
    after = result["calibration"]["after"]["mean"]
    mm, um, m = (_table(texts[u])["cal after"][0] for u in ("auto", "um", "m"))
    assert mm == pytest.approx(after * 1e3, rel=1e-3) and um == pytest.approx(after * 1e6,
                                                                              rel=1e-3)
    assert m == pytest.approx(after, rel=1e-3)
    assert main(["calibrate", str(urdf), str(meas), "--unit", "inch"]) == 2
    assert "option --unit: unknown unit 'inch'" in capsys.readouterr().err


# ---------------------------------------------------------------------------- --help
#: (command, option) -> the fixed set of values --help must list
CHOICES = {
    ("calibrate", "--loss"): ("linear", "huber", "soft_l1", "cauchy", "arctan"),
    ("calibrate", "--unit"): ("auto", "mm", "um", "m"),
    ("simulate", "--errors"): ("zero", "random"),
    ("identifiability", "--free"): ("all", "identifiable"),
    ("handeye", "--setup"): ("eye-in-hand", "eye-to-hand"),
    ("handeye", "--refine"): ("none", "lm", "igwo", "dlh-gwo-de"),
    ("handeye", "--pairs"): ("all", "consecutive"),
    ("handeye-poses", "--scheme"): ("star", "random"),
    ("handeye-images", "--setup"): ("eye-in-hand", "eye-to-hand"),
    ("batch", "--executor"): ("local", "dask"),
    ("compensate", "--base"): ("calibrated", "nominal"),
    ("compensate", "--tool"): ("calibrated", "nominal"),
    ("stewart fk", "--method"): ("newton", "pso"),
}


def _help(command: str, capsys, monkeypatch) -> str:
    monkeypatch.setenv("COLUMNS", "200")
    assert main([*command.split(), "--help"]) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("command, option", sorted(CHOICES))
def test_help_lists_the_choices(command, option, capsys, monkeypatch):
    text = _help(command, capsys, monkeypatch)
    line = next(ln for ln in text.splitlines() if ln.strip().startswith(option + " "))
    assert "[" + "|".join(CHOICES[command, option]) in line, line
    assert "<str>" not in line


def test_help_choices_are_the_valid_values(capsys, monkeypatch):
    """The lists in --help are the sets the code accepts (no drift)."""
    from kinecal.calibration.handeye import METHODS
    from kinecal.calibration.serial.api import CALIBRATION_METHODS
    from kinecal.cli._options import CALIBRATION_METHOD_CHOICES, UNITS
    from kinecal.cli.export import FORMATS
    from kinecal.cli.handeye import HANDEYE_METHODS
    from kinecal.experiments import PAPERS
    from kinecal.metrology.units import DISPLAY_UNITS

    plain = [m for m in CALIBRATION_METHODS if not m.startswith("hybrid-")]
    assert list(CALIBRATION_METHOD_CHOICES[:-1]) == plain
    assert CALIBRATION_METHOD_CHOICES[-1] == "hybrid-<metaheuristic>"
    assert tuple(HANDEYE_METHODS) == tuple(METHODS) and UNITS == DISPLAY_UNITS
    assert "[" + "|".join(FORMATS) + "]" in _help("export", capsys, monkeypatch)
    assert "[" + "|".join(PAPERS) + "]" in _help("reproduce", capsys, monkeypatch)
    assert "[" + "|".join(plain) in _help("calibrate", capsys, monkeypatch)


#: options whose value is a length or an angle: their help names the unit
LENGTHS = {"simulate": ("--noise", "--angle-noise"), "calibrate": ("--target", "--sigma"),
           "handeye-poses": ("--distance", "--radius"), "handeye-images": ("--robot-noise",),
           "stewart simulate": ("--noise-position", "--noise-legs", "--noise-rotation",
                                "--errors")}


@pytest.mark.parametrize("command", sorted(LENGTHS))
def test_length_and_angle_options_name_their_unit(command, capsys, monkeypatch):
    text = _help(command, capsys, monkeypatch)
    blocks = re.split(r"\n  (?=-)", text)
    for option in LENGTHS[command]:
        block = " ".join(next(b for b in blocks if b.startswith(option + " ")).split())
        assert re.search(r"length unit|angle unit|arcsec|\bdeg\b|\bmm\b", block), block


# ---------------------------------------------------------------------------- messages
MISSING = [
    ["calibrate", "ur5", "nope.csv"], ["calibrate", "nope.yaml", "x.csv"],
    ["fk", "ur5", "nope.csv"], ["fk", "ur5", "j.csv", "--params", "nope.json"],
    ["handeye", "nope.csv"], ["handeye", "--robot-poses", "nope.csv", "--target-poses", "n.csv"],
    ["compensate", "nope.json", "p.csv", "--out", "o.csv"],
    ["stewart", "fk", "liu2008-cmm", "nope.csv"], ["stewart", "calibrate", "nope.yaml", "d.csv"],
    ["batch", "nope.yaml", "--out", "o"], ["iso9283", "nope.csv"],
    ["export", "nope.json", "--out", "x.urdf"], ["identifiability", "ur5", "--data", "nope.csv"],
    ["simulate", "ur5", "--joints", "nope.csv", "--out", "o.csv"],
]


@pytest.mark.parametrize("argv", MISSING, ids=lambda a: " ".join(a[:2]))
def test_one_wording_for_a_missing_file(argv, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "j.csv").write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n")
    (tmp_path / "x.csv").write_text("q1,q2,q3,q4,q5,q6,x,y,z\n0,0,0,0,0,0,1,2,3\n")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert re.fullmatch(r"kinecal: error: nope\.\w+(, option [-\w]+)?: file not found"
                        r"( \(nor a bundled [^)]*\))?\n", err), err


def test_progress_without_a_total_shows_the_count():
    from rich.console import Console
    from rich.progress import Progress

    from kinecal.cli._common import progress_columns

    for total, shown, never in ((None, "19 it.", "None"), (40, "19/40", "it.")):
        buf = io.StringIO()
        console = Console(file=buf, force_terminal=True, width=100)
        with Progress(*progress_columns(total), console=console) as bar:
            task = bar.add_task("calibrate", total=total, best="")
            bar.update(task, advance=19)
            bar.refresh()
        assert shown in buf.getvalue() and never not in buf.getvalue()


@pytest.mark.parametrize("sep, name", [(";", "semicolons"), ("\t", "tabs"), ("|", "vertical")])
def test_a_csv_that_does_not_split_names_its_separator(sep, name, tmp_path):
    from kinecal.io.csvtable import read_table
    from kinecal.io.handeye import read_handeye_files
    from kinecal.io.measurements import read_measurements
    from kinecal.io.repeatability import read_repeatability

    path = tmp_path / "t.csv"
    cols = ["q1", "q2", "q3", "q4", "q5", "q6", "x", "y", "z"]
    path.write_text(sep.join(cols) + "\n" + sep.join("1" * 9) + "\n")
    for read in (lambda: read_table(path, ["x"]),
                 lambda: read_measurements(path, kinecal.load_model("ur5")),
                 lambda: read_repeatability(path, None),
                 lambda: read_handeye_files(path, path)):
        with pytest.raises(InputError, match=f"separated by {name}"):
            read()
    # a comma file whose cells hold the character is read as it is
    path.write_text("x,y,z,note\n1,2,3,a;b\n")
    assert read_table(path, ["x", "y", "z"])["x"].tolist() == [1.0]


# ---------------------------------------------------------------------------- data flow
def test_select_poses_feeds_identifiability_and_simulate(tmp_path, capsys):
    q, meas = tmp_path / "q.csv", tmp_path / "meas.csv"
    assert main(["select-poses", "irb120", "--count", "14", "--candidates", "300",
                 "--out", str(q)]) == 0
    assert main(["identifiability", "irb120", "--data", str(q), "--json"]) == 0
    from_joints = json.loads(capsys.readouterr().out)
    assert main(["simulate", "irb120", "--joints", str(q), "--errors", "zero",
                 "--out", str(meas)]) == 0
    capsys.readouterr()
    with open(q, newline="") as a, open(meas, newline="") as b:
        qs, ms = list(csv.DictReader(a)), list(csv.DictReader(b))
    joints = [[[float(r[f"q{i}"]) for i in range(1, 7)] for r in rows] for rows in (qs, ms)]
    np.testing.assert_allclose(joints[1], joints[0], rtol=1e-14)  # deg -> rad -> deg
    model = kinecal.load_model("irb120")
    data = kinecal.read_measurements(meas, model)
    np.testing.assert_allclose(data.xyz, model.positions(data.q), atol=1e-9)  # zero errors
    assert main(["identifiability", "irb120", "--data", str(meas), "--json"]) == 0
    from_measurements = json.loads(capsys.readouterr().out)
    for key in ("rank", "identifiable", "unidentifiable"):
        assert from_joints[key] == from_measurements[key]
    assert from_joints["condition_number"] == pytest.approx(
        from_measurements["condition_number"], rel=1e-9)
    assert main(["simulate", "irb120", "--joints", str(q), "--poses", "3", "--out",
                 str(meas)]) == 2
    assert "option --joints: expected --poses N" in capsys.readouterr().err


def test_coverage_only_where_it_means_something(tmp_path, capsys):
    jobs = tmp_path / "jobs.yaml"
    jobs.write_text("study: {model: irb120, methods: [lm], seeds: 2, noise: [0.02], "
                    "poses: [20]}\n")  # errors: random, the default
    out = tmp_path / "out"
    assert main(["batch", str(jobs), "--out", str(out), "--workers", "1"]) == 0
    cap = capsys.readouterr()
    assert "(no coverage table: jobs with errors: random have errors on parameters" in cap.out
    assert "warning" not in cap.err  # clean simulated jobs: no warning
    assert (out / "study.csv").exists() and not (out / "coverage.csv").exists()


def test_a_pipe_closed_early_is_not_a_failure(tmp_path):
    """``kinecal ... | head -1`` exits 0 (typer ended a broken stdout pipe with 1)."""
    code = "from kinecal.cli import main; main()"
    proc = subprocess.run(["bash", "-o", "pipefail", "-c",
                           f"'{sys.executable}' -c '{code}' identifiability irb120 --poses 12"
                           " | head -1"], cwd=tmp_path, capture_output=True, text=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("rank ")
