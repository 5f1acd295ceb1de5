"""Reports of real results: the hand-eye CLI JSON on the bundled camodocal recording and
the papers/004 reproduction (``experiments.liu2008.run``)."""

import json
import re

from kinecal.cli import main
from kinecal.report.html import handeye_report, reproduce_report


def test_handeye_report_of_the_cli_json(tmp_path, capsys):
    assert main(["handeye", "handeye-camodocal", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    text = handeye_report(result, tmp_path / "he.html").read_text(encoding="utf-8")
    assert "X (cam2base)" in text  # the recording is eye-to-hand
    stations = re.findall(r"<tr><td class=\"l\">(\d+)</td>", text)
    assert stations == [str(k) for k in range(len(result["stations"]))]
    assert text.count("<td>outlier</td>") == len(result["outliers"]) > 0
    assert f"{result['rotation_rms_deg']:.4g}" in text
    assert text.count("data:image/png;base64,") == 1


def test_reproduce_report_of_liu2008(tmp_path):
    from kinecal.experiments import liu2008

    result = liu2008.run(quick=True)
    text = reproduce_report(result, tmp_path / "liu2008.html").read_text(encoding="utf-8")
    for ident in ("rows", "rendered", "details", "figures"):
        assert f'<section id="{ident}">' in text
    # Table 3 of papers/004 beside kinecal's newton value, to 10 significant digits
    for row in result["rows"]:
        assert f"<td class=\"l\">{row['quantity']}</td>" in text
        assert f"{row['newton']:.10g}" in text
    assert "Liu, Liu and Wei (2008), Table 3" in text  # the experiment's own rendering
    assert "pso.history_first_seed" in text  # its convergence curve
