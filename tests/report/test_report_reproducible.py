"""``SOURCE_DATE_EPOCH`` (kinecal._reproducible): the same inputs give the same report, result
JSON and summary byte for byte for every command that writes them; a date before 1970 is
honoured; a malformed value is one line, exit 2; non-UTF-8 text in the record is shown, not
an internal error."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from kinecal.cli import main

SRC = str(Path(__file__).resolve().parents[2] / "src")


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("data")
    for argv in (["simulate", "ur5", "--poses", "40", "--seed", "2", "--out", str(d / "a.csv")],
                 ["simulate", "ur5", "--kind", "ballbar", "--poses", "30", "--seed", "3",
                  "--out", str(d / "bb.csv")],
                 ["stewart", "simulate", "liu2008-cmm", "--poses", "40", "--seed", "4",
                  "--out", str(d / "st.csv")]):
        assert main(argv) == 0
    return d


COMMANDS = {
    "calibrate": ["calibrate", "ur5", "{d}/a.csv", "--out", "r.json", "--report", "r.html"],
    "kinds": ["calibrate", "ur5", "{d}/a.csv", "{d}/bb.csv", "--out", "r.json",
              "--report", "r.html"],
    "handeye": ["handeye", "handeye-tabb1:pairs", "--out", "r.json", "--report", "r.html"],
    "stewart": ["stewart", "calibrate", "liu2008-cmm", "{d}/st.csv", "--out", "r.json",
                "--report", "r.html"],
}


@pytest.mark.parametrize("name", COMMANDS)
def test_two_runs_give_the_same_bytes(data, tmp_path, monkeypatch, capsys, name):
    """The solver's time was in the summary, the report and the result JSON: two runs
    differed although the date was fixed."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    runs = []
    for i in (1, 2):
        folder = tmp_path / f"run{i}"
        folder.mkdir()
        monkeypatch.chdir(folder)
        assert main([a.format(d=data) for a in COMMANDS[name]]) == 0
        summary = capsys.readouterr().out
        runs.append((summary, (folder / "r.json").read_bytes(),
                     (folder / "r.html").read_bytes()))
    assert runs[0] == runs[1]
    summary, result, report = runs[0]
    assert b"2023-11-14T22:13:20+00:00" in report and b"time [s]" not in report
    assert b'"seconds": null' in result or b'"seconds"' not in result
    assert not any(line.rstrip().endswith(" s") for line in summary.splitlines()), summary


def test_without_the_epoch_the_times_are_kept(data, tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    out = tmp_path / "r.json"
    assert main(["calibrate", "ur5", str(data / "a.csv"), "--out", str(out),
                 "--report", str(tmp_path / "r.html")]) == 0
    assert " evaluations, " in capsys.readouterr().out
    assert '"seconds": null' not in out.read_text()
    assert "time [s]" in (tmp_path / "r.html").read_text()


def test_a_date_before_1970_is_honoured(data, tmp_path, monkeypatch):
    """``SOURCE_DATE_EPOCH=-1`` was ignored (the record carried the time of the run)."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "-1")
    rep = tmp_path / "r.html"
    assert main(["calibrate", "ur5", str(data / "a.csv"), "--report", str(rep),
                 "--quiet"]) == 0
    assert "1969-12-31T23:59:59+00:00" in rep.read_text()


@pytest.mark.parametrize("value", ["abc", "1e20", "1.5", "99999999999999999"])
def test_a_malformed_epoch_is_refused_before_any_work(data, tmp_path, value):
    """``abc`` and ``1e20`` were internal errors (numpy's f2py, imported by scipy, reads the
    variable with int()); a date beyond year 9999 too."""
    rep = tmp_path / "r.html"
    p = subprocess.run([sys.executable, "-m", "kinecal", "calibrate", "ur5",
                        str(data / "a.csv"), "--report", str(rep)], capture_output=True,
                       text=True, env={**os.environ, "PYTHONPATH": SRC,
                                       "SOURCE_DATE_EPOCH": value}, timeout=120)
    assert p.returncode == 2, p.stderr
    assert p.stderr.startswith("kinecal: error: SOURCE_DATE_EPOCH=") and \
        p.stderr.count("\n") == 1, p.stderr
    assert "whole seconds since 1970" in p.stderr and not rep.exists()


def test_an_empty_epoch_counts_as_unset(data, tmp_path):
    p = subprocess.run([sys.executable, "-m", "kinecal", "calibrate", "ur5",
                        str(data / "a.csv"), "--quiet"], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": SRC, "SOURCE_DATE_EPOCH": " "},
                       timeout=120)
    assert p.returncode == 0, p.stderr


def test_bytes_that_are_not_utf8_are_shown_in_the_record(data, tmp_path):
    """``--note $'\\xff'`` (and a file name with such bytes) were a UnicodeEncodeError."""
    odd = tmp_path / os.fsdecode(b"cal\xff.csv")
    odd.write_bytes((data / "a.csv").read_bytes())
    rep = tmp_path / "r.html"
    note = os.fsdecode(b"caf\xe9 \xff")
    assert main(["calibrate", "ur5", str(odd), "--report", str(rep), "--note", note,
                 "--operator", "Zo\u00eb", "--quiet"]) == 0
    text = rep.read_text(encoding="utf-8")
    assert "caf\\xe9 \\xff" in text and "cal\\xff.csv" in text and "Zo\u00eb" in text


def test_rendering_a_pdf_leaves_pillow_refusing_truncated_images():
    """WeasyPrint, once imported, made Pillow accept truncated files process-wide: a
    truncated board image then passed kinecal's check (and libjpeg wrote on stderr)."""
    if importlib.util.find_spec("weasyprint") is None:  # imported in the child only
        pytest.skip("PDF reports need the pdf extra")
    code = ("from PIL import ImageFile\n"
            "from kinecal.report.document import check_report_path\n"
            "check_report_path('r.pdf')\n"
            "import weasyprint\n"
            "assert ImageFile.LOAD_TRUNCATED_IMAGES is False\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": SRC}, timeout=120)
    assert p.returncode == 0, p.stderr
