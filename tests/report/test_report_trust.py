"""Report additions of issue 13: the warnings box at the top, per-axis errors, the 95th
percentile, the correlation matrix, units in the confounding table."""

import dataclasses
import math
import re

import numpy as np

import kinecal
from kinecal.calibration.serial.simulate import simulate
from kinecal.data import Measurements
from kinecal.diagnostics import Diagnostic
from kinecal.report.html import calibration_report, fmt, handeye_report


def test_warnings_box_comes_first_and_is_escaped(ur5_result, tmp_path):
    bad = dataclasses.replace(ur5_result, warnings=[
        Diagnostic("scale-mismatch", "positions <look> like metres & more")])
    text = calibration_report(bad, tmp_path / "r.html", pngs={}).read_text(encoding="utf-8")
    assert '<section id="warnings"' in text
    assert text.index('id="warnings"') < text.index('id="summary"')
    assert "positions &lt;look&gt; like metres &amp; more" in text and "[scale-mismatch]" in text
    clean = calibration_report(ur5_result, tmp_path / "c.html", pngs={}).read_text(
        encoding="utf-8")
    assert 'id="warnings"' not in clean
    he = handeye_report({"stations": [], "warnings": [{"code": "few-poses", "message": "m"}]},
                        tmp_path / "h.html").read_text(encoding="utf-8")
    assert he.index('id="warnings"') < he.index('id="summary"')


def test_per_axis_errors_percentile_and_correlations(ur5_result, tmp_path):
    text = calibration_report(ur5_result, tmp_path / "r.html", pngs={}).read_text(
        encoding="utf-8")
    assert "95th percentile [mm]" in text
    assert fmt(ur5_result.calibration_stats["after"]["p95"]) in text
    assert fmt(float(np.percentile(ur5_result.errors_after, 95))) in text
    assert '<section id="axes">' in text and "mean dx [mm]" in text
    axes = ur5_result.extra["axis_errors"]["calibration"]["after"]
    assert fmt(axes["z"]["rms"]) in text
    assert '<section id="correlation">' in text
    cells = re.findall(r'<td style="background:[^"]+;font-size:.75em">([+-][0-9.]+)</td>', text)
    k = math.isqrt(len(cells))
    R = np.array([float(c) for c in cells]).reshape(k, k)
    np.testing.assert_allclose(np.diag(R), 1.0)
    np.testing.assert_allclose(R, R.T)


def test_confounding_table_has_units():
    m = kinecal.load_model("hu2005-scanner")
    sim = simulate(m, 50, errors="random", noise=0.01, rng=1)
    res = kinecal.calibrate(m, Measurements(sim.data.q, sim.data.xyz))
    from kinecal.report.details import confounded_rows

    rows = dict(confounded_rows(res))
    assert rows and all("mm/" in text or "rad/" in text for text in rows.values())
    # an angle of the last link confounded with a length: the coefficient is mm per rad
    assert any(name.startswith(("theta", "alpha")) and "mm/rad" in text
               for name, text in rows.items())
