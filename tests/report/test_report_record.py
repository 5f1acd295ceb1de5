"""A report a metrologist signs: the record (date, version, command line, input SHA-256s,
operator, instrument, note), expanded k = 2 uncertainties, the summary first, the same
report as PDF, and the ISO 9283 section of repeated validation poses."""

import hashlib
import html
import io
import re
import sys
from datetime import UTC, datetime

import numpy as np
import pytest

import kinecal
from kinecal.calibration.serial.simulate import simulate
from kinecal.cli import main
from kinecal.data import Measurements
from kinecal.io.measurements import write_measurements
from kinecal.report.figures import calibration_figures
from kinecal.report.html import calibration_report, fmt
from kinecal.report.provenance import collect

_IMG = re.compile(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


def sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def cal_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cal")
    model = kinecal.load_model("ur5")
    data = simulate(model, 75, errors="random", noise=0.01, rng=7).data
    write_measurements(d / "cal.csv", Measurements(data.q[:60], data.xyz[:60]), model)
    write_measurements(d / "val.csv", Measurements(data.q[60:], data.xyz[60:]), model)
    return d


def test_calibrate_report_carries_the_record_k2_and_the_summary_first(cal_files, capsys):
    d = cal_files
    report, out = d / "r.html", d / "r.json"
    args = ["calibrate", "ur5", str(d / "cal.csv"), "--validate", str(d / "val.csv"), "--quiet",
            "--out", str(out), "--report", str(report), "--operator", "Ada <L>",
            "--instrument", "Tracker AT960 #42", "--note", "20.1 degC, job 7"]
    assert main(args) == 0
    text = report.read_text(encoding="utf-8")
    # date and time, ISO 8601 with its UTC offset, now
    (when,) = re.findall(r'date and time \(ISO 8601\)</td><td class="l">([^<]+)<', text)
    created = datetime.fromisoformat(when)
    assert created.tzinfo is not None
    assert abs((datetime.now(UTC) - created).total_seconds()) < 600
    assert f"kinecal</td><td class=\"l\">{kinecal.__version__}<" in text
    # every input with its SHA-256: the two CSVs and the bundled model file
    for name in ("cal.csv", "val.csv"):
        assert sha(d / name) in text
    from kinecal.io.bundled import input_file

    assert sha(input_file("ur5")) in text and "MODEL (ur5, bundled)" in text
    assert html.escape("Ada <L>") in text and "Tracker AT960 #42" in text
    assert "20.1 degC, job 7" in text
    assert "kinecal calibrate ur5 " in text and "--operator &#x27;Ada &lt;L&gt;&#x27;" in text
    # expanded uncertainties beside the 1-sigma ones, stated as k = 2
    import json

    res = json.loads(out.read_text())
    assert "U (k = 2)" in text and "coverage factor <strong>k = 2</strong>" in text
    free = {n: e for n, e in res["parameters"].items() if e["free"] and e["std"]}
    assert len(free) > 10
    for e in free.values():
        assert f"<td>{fmt(e['std'])}</td><td>{fmt(2 * e['std'])}</td>" in text
    # the summary first: validation before -> after, improvement, warnings
    order = [text.index(f'id="{s}"') for s in ("overview", "provenance", "summary",
                                                 "parameters", "figures")]
    assert order == sorted(order)
    overview = text[order[0]:order[1]]
    val = res["validation"]
    for key in ("mean", "rms", "max"):
        assert f"{fmt(val['before'][key])} &rarr; <strong>{fmt(val['after'][key])}" in overview
    assert f"{res['improvement_percent']:.2f} %" in overview and "Warnings: none." in overview


def test_record_options_need_a_report_and_pdf_needs_weasyprint(cal_files, capsys, monkeypatch,
                                                               tmp_path):
    base = ["calibrate", "ur5", str(cal_files / "cal.csv"), "--quiet"]
    assert main([*base, "--note", "x"]) == 2
    assert "option --note: applies to --report only" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "weasyprint", None)  # as if not installed
    out = tmp_path / "r.json"
    assert main([*base, "--out", str(out), "--report", str(tmp_path / "r.pdf")]) == 2
    err = capsys.readouterr().err
    assert "option --report: PDF reports need WeasyPrint: pip install 'kinecal[pdf]'" in err
    assert list(tmp_path.iterdir()) == []  # refused before any work


def test_same_report_bytes_under_source_date_epoch(ur5_result, tmp_path, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    pngs = calibration_figures(ur5_result)
    a = calibration_report(ur5_result, tmp_path / "a.html", pngs).read_bytes()
    b = calibration_report(ur5_result, tmp_path / "b.html", pngs).read_bytes()
    assert a == b and b"2023-11-14T22:13:20+00:00" in a
    assert b"Python API (no command line)" in a


def test_pdf_is_the_same_report(ur5_result, tmp_path, cal_files):
    """Text, record and every figure of the HTML report are in the PDF (pixels compared)."""
    pypdf = pytest.importorskip("pypdf", reason="pypdf is in the dev extra")
    prov = collect({"DATA": cal_files / "cal.csv"}, command=["kinecal", "calibrate"],
                   operator="Ada", instrument="AT960")
    pngs = calibration_figures(ur5_result)
    page_html = calibration_report(ur5_result, tmp_path / "r.html", pngs, prov)
    pdf = calibration_report(ur5_result, tmp_path / "r.pdf", pngs, prov)
    assert pdf.read_bytes()[:5] == b"%PDF-"
    reader = pypdf.PdfReader(str(pdf))
    assert len(reader.pages) >= 3
    text = " ".join(p.extract_text() for p in reader.pages)
    flat = " ".join(text.split())
    for needle in ("Summary", "Record", prov.created, sha(cal_files / "cal.csv")[:32],
                   "U (k = 2)", "Ada", "AT960", f"{ur5_result.improvement_percent:.2f} %",
                   f"kinecal {kinecal.__version__}", "page 1 of"):
        assert needle in flat, needle
    import matplotlib.image

    html_figs = [matplotlib.image.imread(io.BytesIO(__import__("base64").b64decode(m)))
                 for m in _IMG.findall(page_html.read_text(encoding="utf-8"))]
    unique = {hashlib.sha256(img.data).hexdigest(): img for p in reader.pages
              for img in p.images}  # a page lists the images of every page
    pdf_figs = [np.asarray(img.image.convert("RGB"), float) / 255.0 for img in unique.values()]
    assert len(html_figs) == len(pdf_figs) == 5
    for a in html_figs:  # each figure is in the PDF, lossless: the same pixels
        assert any(a.shape[:2] == b.shape[:2] and np.abs(a[..., :3] - b).max() < 2 / 255
                   for b in pdf_figs)


def test_stewart_and_handeye_reports_carry_the_record(tmp_path, capsys):
    data = tmp_path / "data.csv"
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "60", "--seed", "1",
                 "--out", str(data), "--quiet"]) == 0
    report = tmp_path / "s.html"
    assert main(["stewart", "calibrate", "liu2008-cmm", str(data), "--quiet", "--report",
                 str(report), "--operator", "Bo"]) == 0
    text = report.read_text(encoding="utf-8")
    assert 'id="provenance"' in text and sha(data) in text and ">Bo<" in text
    assert "U (k = 2)" in text
    he = tmp_path / "h.html"
    assert main(["handeye", "handeye-camodocal", "--quiet", "--report", str(he),
                 "--instrument", "cam 1"]) == 0
    text = he.read_text(encoding="utf-8")
    assert 'id="provenance"' in text and "cam 1" in text and "(expanded, k = 2)" in text
    assert "handeye-camodocal, bundled" in text


def test_repeated_validation_poses_get_an_iso9283_section(ur5_result, tmp_path):
    """Validation rows with equal joints are the cycles of a pose: AP before/after and RP,
    the same numbers as the definitions computed here."""
    model = ur5_result.nominal_model
    truth = simulate(model, 75, errors="random", noise=0.01, rng=3).true_params
    rng = np.random.default_rng(11)
    q = np.repeat(rng.uniform(-2, 2, (3, model.n_joints))[None], 6, axis=0).reshape(-1, 6)
    xyz = model.positions(q, truth) + rng.normal(0, 0.01, (len(q), 3))
    val = Measurements(q, xyz)
    text = calibration_report(ur5_result, tmp_path / "r.html", {}, validation=val).read_text(
        encoding="utf-8")
    sec = text[text.index('id="iso9283"'):]
    sec = sec[:sec.index("</section>")]
    for i in range(3):
        rows = xyz[i::3]
        bary = rows.mean(axis=0)
        for m in (model, ur5_result.model):
            ap = np.linalg.norm(bary - m.positions(q[i:i + 1])[0])
            assert f"<td>{fmt(float(ap), 5)}</td>" in sec
        lj = np.linalg.norm(rows - bary, axis=1)
        assert f"<td>{fmt(float(lj.mean() + 3 * lj.std(ddof=1)), 5)}</td>" in sec
    # no repeated poses: no section
    plain = Measurements(rng.uniform(-2, 2, (10, 6)), rng.uniform(-500, 500, (10, 3)))
    text = calibration_report(ur5_result, tmp_path / "p.html", {}, validation=plain).read_text(
        encoding="utf-8")
    assert 'id="iso9283"' not in text
