"""``kinecal calibrate MODEL A.csv B.csv --unit U``: the multi-kind summary shows its lengths
in U, the per-kind table as well as the tracker tables (the numbers scaled, not relabelled)."""

import re

from kinecal.cli import main


def _rows(text: str) -> dict[str, list[float]]:
    """The per-kind rows and the 'cal. after' row of a summary, as numbers."""
    out = {}
    for line in text.splitlines():
        m = re.match(r"(ballbar|point)\s+\S+\s+\d+\s+(\S+?)\*?\s+(\S+)\s+(\S+)\s+(\S+)$", line)
        if m:
            out[m.group(1)] = [float(v) for v in m.groups()[1:]]
        if line.startswith("cal. after"):
            out["after"] = [float(v) for v in line.split()[3:]]  # after n
    return out


def test_unit_scales_every_length_of_a_kinds_summary(tmp_path, capsys):
    bb, pt, truth = (str(tmp_path / n) for n in ("bb.csv", "pt.csv", "t.json"))
    assert main(["simulate", "irb120", "--kind", "ballbar", "--poses", "20", "--noise", "0.002",
                 "--seed", "1", "--out", bb, "--truth-out", truth, "--quiet"]) == 0
    assert main(["simulate", "irb120", "--kind", "point", "--poses", "8", "--noise", "0.01",
                 "--errors", truth, "--seed", "2", "--out", pt, "--quiet"]) == 0
    capsys.readouterr()
    shown = {}
    for unit in ("mm", "um"):
        assert main(["calibrate", "irb120", bb, pt, "--unit", unit]) == 0
        text = capsys.readouterr().out
        assert f"error per observation [{unit}]" in text
        assert f"(rms, max: error per observation, {unit})" in text
        shown[unit] = _rows(text)
    assert set(shown["mm"]) == {"ballbar", "point", "after"}
    for key, mm in shown["mm"].items():
        for a, b in zip(mm, shown["um"][key], strict=True):
            assert abs(b - 1000.0 * a) <= 1e-3 * abs(b) + 1e-9, (key, a, b)
