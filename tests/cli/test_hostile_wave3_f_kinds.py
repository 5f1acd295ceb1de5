"""Wave 3 hostile sweep of the measurement kinds, ``kinecal iso9283`` and ``load_result``
(branch f-kinds): each test pins a case that misbehaved before its fix.

The contract (tests/cli/test_hostile_issue28.py): exit 2 with one line naming the file and
the reason, and nothing written; or exit 0 with a ``kinecal: warning: ... [CODE]`` line on
implausible input; clean input stays silent.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import kinecal
from kinecal import diagnostics
from kinecal.calibration.diagnostics.fit import check_unidentifiable_free
from kinecal.cli import main

_WARNING = re.compile(r"^kinecal: warning: .+ \[([a-z-]+)\]$")

ISO = """pose,cycle,x,y,z,cx,cy,cz
P1,1,600.061,-200.018,400.022,600,-200,400
P2,1,500.047,0.012,300.031,500,0,300
P3,1,400.052,200.020,500.019,400,200,500
P1,2,600.048,-200.025,400.030,,,
P2,2,500.055,0.020,300.024,,,
P3,2,400.041,200.011,500.027,,,
P1,3,600.057,-200.014,400.017,,,
P2,3,500.050,0.008,300.036,,,
P3,3,400.049,200.026,500.012,,,
"""


def run(argv: list, capsys) -> tuple[int, str, list[str], list[str]]:
    """Exit status, stdout, warning codes and error lines (nothing else on stderr)."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    codes = [m.group(1) for m in map(_WARNING.match, lines) if m]
    errors = [line for line in lines if line.startswith("kinecal: error: ")]
    progress = [line for line in lines if line.startswith("wrote ")]
    assert len(codes) + len(errors) + len(progress) == len(lines), err
    return code, out, codes, errors


@pytest.fixture(scope="module")
def kinds(tmp_path_factory) -> Path:
    """A ballbar (2 pivots x 20 rows), sockets (4 x 8 touches) and tracker file of one
    perturbed IRB-120."""
    d = tmp_path_factory.mktemp("f-kinds")
    sim = ["simulate", "irb120", "--noise", "0.002", "--quiet"]
    assert main([*sim, "--kind", "ballbar", "--poses", "20", "--seed", "1", "--out",
                 str(d / "ballbar.csv"), "--truth-out", str(d / "truth.json")]) == 0
    assert main([*sim, "--kind", "point", "--poses", "8", "--errors", str(d / "truth.json"),
                 "--seed", "2", "--out", str(d / "sockets.csv")]) == 0
    assert main([*sim, "--poses", "20", "--errors", str(d / "truth.json"), "--seed", "3",
                 "--out", str(d / "tracker.csv")]) == 0
    return d


def _lines(path: Path) -> list[str]:
    return path.read_text(encoding="utf-8").strip().splitlines()


def _copy_first_row(src: Path, dst: Path, n: int) -> Path:
    head, first = _lines(src)[:2]
    dst.write_text(head + "\n" + (first + "\n") * n, encoding="utf-8")
    return dst


@pytest.mark.parametrize("kind", ["sockets", "ballbar"])
def test_one_touch_repeated_is_one_touch(kind, kinds, tmp_path, capsys):
    """1000 copies of one row gave a point (or a pivot) 1000 'touches': a point was solved
    from one arm configuration, silently (1e5 copies ran for minutes)."""
    bad = _copy_first_row(kinds / f"{kind}.csv", tmp_path / "copies.csv", 1000)
    out = tmp_path / "result.json"
    code, _, _, errors = run(["calibrate", "irb120", kinds / "ballbar.csv", bad, "--out", out,
                              "--quiet"], capsys)
    assert code == 2 and not out.exists()
    assert len(errors) == 1 and "copies.csv" in errors[0]
    assert "1000 rows" in errors[0] and "1 distinct arm configuration" in errors[0]


def test_pair_of_one_configuration_refused(kinds, tmp_path, capsys):
    """A bar 'measured' with both ends in one arm configuration (a copied row)."""
    rows = _lines(kinds / "ballbar.csv")[1:]
    q = [",".join(r.split(",")[:6]) for r in rows]
    text = "q1,q2,q3,q4,q5,q6,pair,distance\n" + "".join(
        f"{q[k]},{k // 2},150\n{q[k] if k % 4 else q[k + 1]},{k // 2},150\n"
        for k in range(0, 20, 2))
    (tmp_path / "pairs.csv").write_text(text, encoding="utf-8")
    code, _, _, errors = run(["calibrate", "irb120", kinds / "ballbar.csv",
                              tmp_path / "pairs.csv", "--quiet"], capsys)
    assert code == 2 and len(errors) == 1
    assert "pairs.csv" in errors[0] and "pair '1' has 2 rows" in errors[0]
    assert "distinct" in errors[0]


def test_repeated_rows_of_a_gauge_or_tracker_warn(kinds, tmp_path, capsys):
    """Repeated rows in a mix were silent (the tracker path alone warns duplicate-poses)."""
    lines = _lines(kinds / "sockets.csv")
    (tmp_path / "sockets.csv").write_text("\n".join(lines + lines[1:4]) + "\n",
                                          encoding="utf-8")
    code, _, codes, _ = run(["calibrate", "irb120", kinds / "ballbar.csv",
                             tmp_path / "sockets.csv", "--quiet"], capsys)
    assert code == 0 and "duplicate-poses" in codes
    track = _copy_first_row(kinds / "tracker.csv", tmp_path / "tracker.csv", 20)
    code, _, codes, _ = run(["calibrate", "irb120", kinds / "ballbar.csv", track, "--quiet"],
                            capsys)
    assert code == 0 and "duplicate-poses" in codes
    code, _, codes, _ = run(["calibrate", "irb120", kinds / "ballbar.csv",
                             kinds / "sockets.csv", kinds / "tracker.csv", "--quiet"], capsys)
    assert code == 0 and codes == []  # clean files stay silent


def test_iso9283_huge_commanded_cell_refused_before_the_report(tmp_path, capsys):
    """cz = 1e308 overflowed AP to inf and the report's figure failed (exit 1)."""
    (tmp_path / "iso.csv").write_text(ISO.replace("400,200,500", "400,200,1e308"),
                                      encoding="utf-8")
    report = tmp_path / "r.html"
    code, _, _, errors = run(["iso9283", tmp_path / "iso.csv", "--report", report], capsys)
    assert code == 2 and not report.exists()
    assert "iso.csv, row 3: column cz" in errors[0] and "1e308" in errors[0]


@pytest.mark.parametrize(("edit", "expected"), [
    (lambda t: t.replace("400,200,500", "400,200,-0"), ["far-from-commanded"]),
    # a 400 mm typo in one of 3 cycles moves the barycentre 133 mm as well
    (lambda t: t.replace("P3,2,400.041", "P3,2,0.041"), ["far-from-commanded", "cycle-scatter"]),
    (lambda t: "\n".join(",".join(c if i < 2 or not c else repr(float(c) / 1000)
                                  for i, c in enumerate(line.split(",")))
                         if k else line for k, line in enumerate(t.splitlines())),
     ["scale-mismatch"]),
])
def test_iso9283_implausible_test_warns(edit, expected, tmp_path, capsys):
    """A commanded typo (AP 500 mm on RP 0.02 mm), a measured typo in one cycle and a file
    in metres read as millimetres gave figures without a word."""
    (tmp_path / "iso.csv").write_text(edit(ISO), encoding="utf-8")
    status, out, codes, _ = run(["iso9283", tmp_path / "iso.csv"], capsys)
    assert status == 0 and codes == expected and "ISO 9283" in out
    status, _, _, errors = run(["iso9283", tmp_path / "iso.csv", "--strict"], capsys)
    assert status == 2 and errors
    (tmp_path / "clean.csv").write_text(ISO, encoding="utf-8")
    assert run(["iso9283", tmp_path / "clean.csv"], capsys)[2] == []


def test_unidentifiable_after_identifiable_does_not_blame_a_free_list():
    """free="identifiable" whose fit went far from nominal said 'the explicit free list
    frees ...; use --free identifiable' (what the user had done)."""
    with diagnostics.collect() as found:
        check_unidentifiable_free(["d4", "a2"], "identifiable")
        check_unidentifiable_free(["d4"], ["d4", "a2"])
    first, second = (d.message for d in found)
    assert "identifiable at the nominal geometry" in first and "free list" not in first
    assert "the explicit free list" in second


def test_stated_noise_below_double_resolution_refused(kinds, tmp_path, capsys):
    """--sigma 1e-300 ended in a ZeroDivisionError (one tracker file) or an SVD failure (a
    mix), exit 1; so did a sigma column of 1e-300."""
    out = tmp_path / "result.json"
    for files in ([kinds / "tracker.csv"], [kinds / "ballbar.csv", kinds / "sockets.csv"]):
        code, _, _, errors = run(["calibrate", "irb120", *files, "--sigma", "1e-300",
                                  "--out", out, "--quiet"], capsys)
        assert code == 2 and not out.exists()
        assert errors[0].startswith("kinecal: error: option --sigma: a stated noise of 1e-300")
    lines = _lines(kinds / "sockets.csv")
    (tmp_path / "sig.csv").write_text("\n".join([lines[0] + ",sigma"] + [
        row + (",1e-300" if k == 3 else ",0.01") for k, row in enumerate(lines[1:])]) + "\n",
        encoding="utf-8")
    code, _, _, errors = run(["calibrate", "irb120", kinds / "ballbar.csv", tmp_path / "sig.csv",
                              "--quiet"], capsys)
    assert code == 2 and "sig.csv: column sigma: a stated noise of 1e-300" in errors[0]
    with pytest.raises(kinecal.InputError, match="below the resolution"):
        kinecal.calibrate("irb120", [kinds / "ballbar.csv", kinds / "sockets.csv"],
                          sigma=[1e-300, None])


def test_pessimistic_stated_noise_of_a_gauge_warns(kinds, capsys):
    """--sigma 100 (mm, on 2 um readings) was silent in a mix; one tracker file warns."""
    argv = ["calibrate", "irb120", kinds / "ballbar.csv", kinds / "sockets.csv", "--quiet"]
    code, _, codes, _ = run([*argv, "--sigma", "100"], capsys)
    assert code == 0 and codes == ["residual-below-noise", "residual-below-noise"]
    code, _, codes, _ = run([*argv, "--sigma", "0.002,0.002"], capsys)  # the truth
    assert code == 0 and codes == []


@pytest.mark.parametrize("argv", [
    ["simulate", "irb120", "--kind", "point", "--poses", "10", "--groups", "1000000",
     "--out", "{d}/o.csv"],
    ["simulate", "irb120", "--kind", "pair", "--poses", "10001", "--out", "{d}/o.csv"],
    ["select-poses", "irb120", "--kind", "ballbar", "--count", "20", "--candidates",
     "1000000", "--out", "{d}/o.csv"],
])
def test_gauge_simulation_size_refused_up_front(argv, tmp_path, capsys):
    """--groups 1000000 (10 million inverse kinematics solves) ran for hours."""
    code, _, _, errors = run([a.format(d=tmp_path) for a in argv], capsys)
    assert code == 2 and not (tmp_path / "o.csv").exists()
    assert "rows asked for" in errors[0] and "expected at most 20000" in errors[0]


def test_validation_file_of_another_robot_warns(kinds, tmp_path, capsys):
    """A UR5 tracker file as --validate of an IRB-120 mix gave its before/after figures
    without a word (validation sets of the stacked path had no checks)."""
    ur5 = tmp_path / "ur5.csv"
    assert main(["simulate", "ur5", "--poses", "20", "--seed", "4", "--out", str(ur5),
                 "--quiet"]) == 0
    argv = ["calibrate", "irb120", kinds / "ballbar.csv", kinds / "sockets.csv", "--quiet"]
    code, _, codes, _ = run([*argv, "--validate", ur5], capsys)
    assert code == 0 and "initial-error" in codes
    code, _, codes, _ = run([*argv, "--validate", kinds / "tracker.csv"], capsys)
    assert code == 0 and codes == []


def test_one_file_twice_warns_in_calibrate_and_identifiability(kinds, tmp_path, capsys):
    """The same sockets twice (or a copy) counted twice, silently; identifiability of a mix
    ran no file checks at all (a UR5 file in an IRB-120 plan was silent)."""
    copy = tmp_path / "copy.csv"
    copy.write_bytes((kinds / "sockets.csv").read_bytes())
    code, _, codes, _ = run(["calibrate", "irb120", kinds / "ballbar.csv",
                             kinds / "sockets.csv", copy, "--quiet"], capsys)
    assert code == 0 and codes == ["duplicate-poses"]
    code, _, codes, _ = run(["identifiability", "irb120", "--data", kinds / "sockets.csv",
                             "--data", kinds / "sockets.csv", "--json"], capsys)
    assert code == 0 and codes == ["duplicate-poses"]
    ur5 = tmp_path / "ur5.csv"
    assert main(["simulate", "ur5", "--poses", "20", "--out", str(ur5), "--quiet"]) == 0
    code, _, codes, _ = run(["identifiability", "irb120", "--data", kinds / "ballbar.csv",
                             "--data", ur5], capsys)
    assert code == 0 and "initial-error" in codes
    code, _, codes, _ = run(["identifiability", "irb120", "--data", kinds / "ballbar.csv",
                             "--data", kinds / "sockets.csv"], capsys)
    assert code == 0 and codes == []
