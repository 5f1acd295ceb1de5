"""HTML reports: sections, embedded figures, escaping, atomic writes; notebook plots."""

import base64
import dataclasses
import re
import struct

import numpy as np
import pytest

from kinecal.errors import InputError
from kinecal.report import figures
from kinecal.report.html import (
    FIG_HEIGHT,
    FIG_WIDTH,
    calibration_report,
    fmt,
    handeye_report,
    reproduce_report,
)

_IMG = re.compile(r'<img class="fig" src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


def embedded_pngs(text):
    """Decoded PNG bytes of every embedded figure of a report."""
    return [base64.b64decode(m) for m in _IMG.findall(text)]


def png_size(data):
    """(width, height) from the PNG IHDR chunk."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def png_pixels(data):
    import io

    import matplotlib.image

    return matplotlib.image.imread(io.BytesIO(data), format="png")


def test_calibration_report_sections_numbers_and_figures(ur5_result, tmp_path):
    res = ur5_result
    path = calibration_report(res, tmp_path / "sub" / "r.html")
    text = path.read_text(encoding="utf-8")
    for ident in ("summary", "identifiability", "errors", "parameters", "figures"):
        assert f'<section id="{ident}">' in text
    # self-contained: no script, no external resource
    assert "<script" not in text and "http://" not in text and "https://" not in text
    # every parameter appears in the table, free ones with their standard error
    table = res.parameter_table()
    for name in table:
        assert f"<td class=\"l\">{name}</td>" in text
    some_free = next(n for n, e in table.items() if e["free"])
    assert fmt(table[some_free]["std"]) in text
    # unidentifiable parameters and the rank are reported
    rep = res.identifiability
    assert f"{rep.rank} of {len(rep.names)}" in text
    for name in rep.unidentifiable:
        assert f"<td class=\"l\">{name}</td>" in text
    # before/after statistics, the same numbers as the result
    for group in (res.calibration_stats, res.validation_stats):
        for when in ("before", "after"):
            assert fmt(group[when]["rms"]) in text
            assert fmt(group[when]["max"]) in text
    assert f"{res.improvement_percent:.2f} %" in text
    # five embedded PNG figures of the announced size, each actually drawn
    pngs = embedded_pngs(text)
    assert len(pngs) == 5
    assert text.count(f'width="{FIG_WIDTH}" height="{FIG_HEIGHT}"') == 5
    for data in pngs:
        assert png_size(data) == (FIG_WIDTH, FIG_HEIGHT)
        px = png_pixels(data)[..., :3]
        nonwhite = (px.min(axis=2) < 0.9).mean()
        assert 0.02 < nonwhite < 0.9


def test_per_pose_figure_shows_the_after_errors_below_the_before_errors(ur5_result):
    _, ax = figures.new_figure()
    figures.plot_calibration(ur5_result, "errors", ax)
    before, after = ax.containers[:2]  # a pair of bars per pose (60 poses)
    top = [np.array([bar.get_height() for bar in c]) for c in (before, after)]
    np.testing.assert_allclose(top[0], ur5_result.errors_before)
    np.testing.assert_allclose(top[1], ur5_result.errors_after)
    assert (top[1] < top[0]).mean() > 0.9
    # pose numbers are whole: no tick at 2.5
    ticks = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
    assert ticks and all(float(t).is_integer() for t in ticks)
    assert min(bar.get_width() for bar in before) >= 0.3  # bars, not hairlines


def test_per_pose_figure_of_many_poses_keeps_pose_order_and_the_sorted_view_sorts(ur5_result):
    rng = np.random.default_rng(0)
    many = dataclasses.replace(ur5_result, errors_before=rng.uniform(1, 3, 1000),
                               errors_after=rng.uniform(0.01, 0.03, 1000))
    _, ax = figures.new_figure()
    figures.plot_calibration(many, "errors", ax)
    assert ax.get_yscale() == "log"
    before, after = ax.get_lines()[:2]
    # pose order: pose k (from 1) at x = k, its own error
    np.testing.assert_array_equal(before.get_xdata(), np.arange(1, 1001))
    np.testing.assert_allclose(before.get_ydata(), many.errors_before)
    np.testing.assert_allclose(after.get_ydata(), many.errors_after)
    _, ax = figures.new_figure()
    figures.plot_calibration(many, "sorted", ax)
    assert ax.get_yscale() == "log"
    lines = {line.get_label(): line for line in ax.get_lines()}
    np.testing.assert_allclose(lines["calibration, before"].get_ydata(),
                               np.sort(many.errors_before)[::-1])
    np.testing.assert_allclose(lines["calibration, after"].get_ydata(),
                               np.sort(many.errors_after)[::-1])
    np.testing.assert_allclose(lines["validation, after"].get_ydata(),
                               np.sort(many.val_after)[::-1])


def test_per_pose_bars_go_logarithmic_when_the_after_errors_would_vanish(ur5_result):
    _, ax = figures.new_figure()
    figures.plot_calibration(ur5_result, "errors", ax)  # after ~ 1/300 of before
    assert ax.get_yscale() == "log"
    close = dataclasses.replace(ur5_result, errors_after=ur5_result.errors_before * 0.5)
    _, ax = figures.new_figure()
    figures.plot_calibration(close, "errors", ax)
    assert ax.get_yscale() == "linear"


def test_plot_for_notebooks_every_kind_and_bad_kinds(ur5_result):
    import matplotlib.pyplot as plt

    for kind in figures.CALIBRATION_KINDS:
        ax = ur5_result.plot(kind)
        assert ax.has_data()
        plt.close(ax.figure)
    ax = ur5_result.plot("convergence")
    line = ax.get_lines()[0]
    np.testing.assert_allclose(line.get_ydata(), ur5_result.history)
    plt.close(ax.figure)
    with pytest.raises(InputError, match="unknown plot kind"):
        ur5_result.plot("pie")
    no_val = dataclasses.replace(ur5_result, val_before=None, val_after=None)
    with pytest.raises(InputError, match="no validation poses"):
        no_val.plot("validation")
    assert len(figures.calibration_figures(no_val)) == 4


def test_user_strings_are_escaped(ur5_result, tmp_path):
    evil = '<script>alert("x")</script>&<b>'
    nominal = ur5_result.nominal_model.with_params(ur5_result.nominal_model.nominal, name=evil)
    res = dataclasses.replace(ur5_result, nominal_model=nominal, method="lm<i>",
                              message="done <now> & 'then'")
    text = calibration_report(res, tmp_path / "r.html", pngs={}).read_text(encoding="utf-8")
    assert "<script" not in text and "<b>" not in text and "lm<i>" not in text
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;&amp;&lt;b&gt;" in text
    assert "done &lt;now&gt; &amp; &#x27;then&#x27;" in text


def test_failed_report_leaves_an_existing_file_untouched(ur5_result, tmp_path, monkeypatch):
    path = tmp_path / "report.html"
    path.write_text("previous report", encoding="utf-8")

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr("kinecal.report.html.page", broken)
    with pytest.raises(RuntimeError):
        calibration_report(ur5_result, path, pngs={})
    assert path.read_text(encoding="utf-8") == "previous report"
    assert [p.name for p in tmp_path.iterdir()] == ["report.html"]


def test_handeye_report_stations_outliers_and_figure(tmp_path):
    rng = np.random.default_rng(0)
    rot = rng.uniform(0.01, 0.2, 12)
    rot[7] = 3.0
    result = {
        "file": "pairs<1>.csv", "X": np.eye(4).tolist(), "setup": "eye-in-hand",
        "method": "park", "refine": "lm", "rotation_rms_deg": 0.9, "translation_rms": 0.4,
        "stations": [{"rotation_deg": float(r), "translation": 0.1 * k}
                     for k, r in enumerate(rot)],
        "outliers": [7], "seed": 0,
    }
    text = handeye_report(result, tmp_path / "he.html").read_text(encoding="utf-8")
    for ident in ("summary", "transform", "figures", "stations"):
        assert f'<section id="{ident}">' in text
    assert "pairs&lt;1&gt;.csv" in text and "pairs<1>" not in text
    assert "X (cam2flange)" in text
    assert text.count("<td>outlier</td>") == 1
    rows = re.findall(r"<tr><td class=\"l\">(\d+)</td>", text)
    assert rows == [str(k) for k in range(12)]
    (png,) = embedded_pngs(text)
    assert png_size(png) == (FIG_WIDTH, FIG_HEIGHT)
    # the outlier's bar is drawn in red
    px = png_pixels(png)[..., :3]
    red = (px[..., 0] > 0.75) & (px[..., 1] < 0.3) & (px[..., 2] < 0.3)
    assert red.sum() > 50


def test_reproduce_report_rows_details_and_histories(tmp_path):
    result = {
        "paper": "demo-paper", "source": "papers/999 Table 1",
        "rows": [{"quantity": "x", "paper": 1.5, "kinecal": 1.5004},
                 {"quantity": "y<z", "paper": 2.0, "kinecal": 1.9999}],
        "pso": {"seeds": 10, "history_first_seed": list(np.geomspace(1.0, 1e-6, 30))},
        "modes": {"total": 16, "poses": [[0.0] * 6] * 16},
    }
    text = reproduce_report(result, tmp_path / "rep.html").read_text(encoding="utf-8")
    assert "<th>kinecal</th>" in text and "y&lt;z" in text
    assert "1.5004" in text and "pso.seeds" in text and "[16 values]" in text
    assert '<section id="rendered">' not in text  # unknown paper: no text rendering
    (png,) = embedded_pngs(text)
    assert png_size(png) == (FIG_WIDTH, FIG_HEIGHT)
