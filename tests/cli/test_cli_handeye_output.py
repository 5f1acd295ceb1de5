"""``kinecal handeye`` output: units on every length, the uncertainty of X, the target pose
(summary text, JSON and HTML report)."""

from __future__ import annotations

import json

from kinecal.cli import main


def test_summary_has_units_uncertainty_and_target(capsys):
    assert main(["handeye", "handeye-camodocal"]) == 0
    text = capsys.readouterr().out
    assert "X (cam2base; translation in m)" in text
    assert "X uncertainty (1 sigma" in text and " m\n" in text
    assert "target pose (target2flange; translation in m)" in text
    rms_line = text.split("translation rms")[1].split("\n")[0]
    assert rms_line.endswith(" m")


def test_unit_option_json_and_report(tmp_path, capsys):
    report = tmp_path / "r.html"
    assert main(["handeye", "handeye-tabb1", "--unit", "mm", "--json", "--report",
                 str(report)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["length_unit"] == "mm" and out["x_uncertainty"]["translation"] > 0
    html = report.read_text()
    assert "Target pose (target2base)" in html and "t [mm]" in html
    assert "X uncertainty, translation [mm]" in html and "translation rms [mm]" in html
    assert main(["handeye", "handeye-tabb1", "--unit", " "]) == 2
