"""Issue 13's corpus: every implausible input it lists, through the command line.

The contract: exit 2 with one clear line, or exit 0 with a ``kinecal: warning: ... [CODE]``
line naming the problem; never an improvement without a warning. Clean inputs stay
silent. (The same checks on more data, both sides of every code, are in
tests/calibration/test_diagnostics_*.py.)
"""

import json
import re
from pathlib import Path

import numpy as np
import pytest

import kinecal
from kinecal.calibration.serial.simulate import simulate, write_truth
from kinecal.calibration.stewart.calibrate import perturb_geometry, simulate_stewart
from kinecal.cli import main
from kinecal.data import Measurements
from kinecal.io.csvtable import write_table
from kinecal.io.geometry import load_geometry
from kinecal.io.measurements import write_measurements
from kinecal.kinematics.stewart.platform import radians_to_degrees

_WARNING = re.compile(r"^kinecal: warning: .+ \[([a-z-]+)\]$")


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    """The issue's files: an IRB-120 simulation (noise 10 um) and variants of it."""
    d = tmp_path_factory.mktemp("corpus")
    m = kinecal.load_model("irb120")
    sim = simulate(m, 40, errors="random", noise=0.01, rng=1)
    q, xyz = sim.data.q, sim.data.xyz
    files = {}

    def put(name, q_, xyz_):
        files[name] = str(d / f"{name}.csv")
        write_measurements(files[name], Measurements(q_, xyz_), m)

    put("clean", q, xyz)
    put("val", *(lambda v: (v.q, v.xyz))(simulate(m, 20, errors=sim.true_params - m.nominal,
                                                  noise=0.01, rng=2).data))
    put("metres", q, xyz / 1000.0)
    put("one", q[:1], xyz[:1])
    put("one3", q[[0, 0, 0]], xyz[[0, 0, 0]])
    put("zneg", q, xyz * [1, 1, -1])
    put("dup10", np.repeat(q, 10, 0), np.repeat(xyz, 10, 0))
    out = xyz.copy()
    out[5, 2] += 50.0
    put("outlier", q, out)
    put("xplus5", q, xyz + [5.0, 0.0, 0.0])
    q1 = np.repeat(q[:1], 40, 0)
    q1[:, 0] = np.linspace(-2.5, 2.5, 40)
    put("onejoint", q1, simulate(m, 0, errors=sim.true_params - m.nominal, noise=0.01, q=q1,
                                 rng=3).data.xyz)
    rad = (d / "clean.csv").read_text().splitlines()
    head, rows = rad[0], [r.split(",") for r in rad[1:]]
    files["radians"] = str(d / "radians.csv")
    (d / "radians.csv").write_text(head + "\n" + "\n".join(
        ",".join([f"{np.radians(float(v)):.17g}" for v in r[:6]] + r[6:]) for r in rows) + "\n")
    # Stewart: simulated data and its variants (poses in degrees as the files expect)
    geom = load_geometry("liu2008-cmm")
    st = simulate_stewart(perturb_geometry(geom, 1e-3, 0), 30, rng=1)
    deg = radians_to_degrees(st.poses)

    def put_st(name, poses, legs):
        files[name] = str(d / f"{name}.csv")
        cols = {c: poses[:, k] for k, c in enumerate(("x", "y", "z", "alpha", "beta", "gamma"))}
        cols.update({f"l{k + 1}": legs[:, k] for k in range(6)})
        write_table(files[name], cols)

    put_st("st_clean", deg, st.legs)
    put_st("st_same", np.repeat(deg[:1], 60, 0), np.repeat(st.legs[:1], 60, 0))
    put_st("st_7", deg[:7], st.legs[:7])
    mm = deg.copy()
    mm[:, :3] *= 1000.0
    put_st("st_mm", mm, st.legs * 1000.0)
    put_st("st_rad", np.column_stack([deg[:, :3], np.radians(deg[:, 3:])]), st.legs)
    # fk --params: results of another model, empty, NaN; a model file with d: .nan
    puma = kinecal.load_model("puma560")
    psim = simulate(puma, 40, errors="random", noise=0.01, rng=4)
    files["puma"] = str(d / "puma.csv")
    write_measurements(files["puma"], psim.data, puma)
    files["puma_result"] = str(d / "puma_result.json")
    assert main(["calibrate", "puma560", files["puma"], "--out", files["puma_result"],
                 "--quiet"]) == 0
    files["empty_result"] = str(d / "empty.json")
    (d / "empty.json").write_text("{}")
    files["nan_result"] = str(d / "nan.json")
    r = json.loads((d / "puma_result.json").read_text())
    r["parameters"]["d3"]["identified"] = float("nan")
    (d / "nan.json").write_text(json.dumps(r))  # writes NaN, which Python's reader accepts
    files["nan_model"] = str(d / "nan_model.yaml")
    puma_yaml = (Path(kinecal.__file__).parent / "robots" / "puma560.yaml").read_text()
    (d / "nan_model.yaml").write_text(puma_yaml.replace(
        "{theta: 0, d: 0, a: 431.8, alpha: 0}", "{theta: 0, d: .nan, a: 431.8, alpha: 0}"))
    files["truth"] = str(d / "truth.json")
    write_truth(files["truth"], m, sim.true_params)
    files["dir"] = str(d)
    return files


def run(argv, files, capsys):
    """Exit status, stdout, the warning codes on stderr and the error line (if any)."""
    argv = [a.format(**files) if "{" in a else a for a in argv]
    code = main(argv)
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    codes = [m.group(1) for m in map(_WARNING.match, lines) if m]
    errors = [line for line in lines if line.startswith("kinecal: error: ")]
    assert len(codes) + len(errors) == len(lines), err  # nothing else on stderr
    return code, out, codes, errors


# (id, argv, expected: "exit2" or the warning code that must name the problem)
CASES = [
    ("metres-for-mm", ["calibrate", "irb120", "{metres}"], "scale-mismatch"),
    ("one-pose", ["calibrate", "irb120", "{one}"], "exit2"),
    ("one-pose-three-times", ["calibrate", "irb120", "{one3}"], "exit2"),
    ("radians-in-degree-file", ["calibrate", "irb120", "{radians}"], "joint-units"),
    ("z-negated", ["calibrate", "irb120", "{zneg}"], "mirrored-frame"),
    ("ur5-data-as-irb120", ["calibrate", "irb120", "ur5-laser-tracker:random"],
     "initial-error"),
    ("only-q1-moves", ["calibrate", "irb120", "{onejoint}"], "rank-deficient"),
    ("rows-duplicated-10x", ["calibrate", "irb120", "{dup10}"], "duplicate-poses"),
    ("one-z-off-by-50", ["calibrate", "irb120", "{outlier}"], "outliers"),
    ("x-plus-5", ["calibrate", "irb120", "{xplus5}"], "residual-offset"),
    ("free-all", ["calibrate", "irb120", "{clean}", "--free", "all"], "unidentifiable-free"),
    ("free-d2-d3", ["calibrate", "irb120", "{clean}", "--free", "d2,d3"],
     "unidentifiable-free"),
    ("validate-is-calibration", ["calibrate", "irb120", "{clean}", "--validate", "{clean}"],
     "validation-overlap"),
    ("stewart-identical-rows", ["stewart", "calibrate", "liu2008-cmm", "{st_same}"], "exit2"),
    ("stewart-7-rows", ["stewart", "calibrate", "liu2008-cmm", "{st_7}"], "exit2"),
    ("stewart-mm-for-m", ["stewart", "calibrate", "liu2008-cmm", "{st_mm}"], "scale-mismatch"),
    ("stewart-radians", ["stewart", "calibrate", "liu2008-cmm", "{st_rad}"], "angle-units"),
    ("fk-result-of-another-model", ["fk", "kr6-craig", "{puma}", "--params", "{puma_result}"],
     "exit2"),
    ("fk-empty-result", ["fk", "puma560", "{puma}", "--params", "{empty_result}"], "exit2"),
    ("fk-nan-result", ["fk", "puma560", "{puma}", "--params", "{nan_result}"], "exit2"),
    ("fk-nan-model", ["fk", "{nan_model}", "{puma}"], "exit2"),
    ("identifiability-one-joint", ["identifiability", "irb120", "--data", "{onejoint}"],
     "rank-deficient"),
]


@pytest.mark.parametrize(("argv", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_every_listed_case_is_refused_or_warned(argv, expected, corpus, capsys):
    json_run = argv[0] == "calibrate" or argv[:2] == ["stewart", "calibrate"]
    code, out, codes, errors = run(argv + (["--json"] if json_run else []), corpus, capsys)
    if expected == "exit2":
        assert code == 2 and len(errors) == 1, (code, errors, codes)
        return
    assert code == 0, errors
    assert expected in codes, codes
    if json_run:  # never an improvement without a warning, in the JSON as on stderr
        result = json.loads(out)
        assert {w["code"] for w in result["warnings"]} >= set(codes)


def test_strict_turns_the_warning_into_exit_2_before_any_output(corpus, capsys, tmp_path):
    out = tmp_path / "r.json"
    code, _, codes, errors = run(["calibrate", "irb120", corpus["metres"], "--strict",
                                  "--out", str(out)], corpus, capsys)
    assert code == 2 and codes == [] and "[scale-mismatch]" in errors[0]
    assert "--strict" in errors[0] and not out.exists()


def test_quiet_silences_the_summary_never_a_warning(corpus, capsys):
    code, out, codes, _ = run(["calibrate", "irb120", corpus["metres"], "--quiet"], corpus,
                              capsys)
    assert code == 0 and out == "" and "scale-mismatch" in codes
    code, out, codes, _ = run(["calibrate", "irb120", corpus["clean"], "--quiet"], corpus,
                              capsys)
    assert code == 0 and out == "" and codes == []


def test_one_joint_uncertainty_is_not_small_and_text_agrees_with_json(corpus, capsys):
    code, out, codes, _ = run(["calibrate", "irb120", corpus["onejoint"], "--json"], corpus,
                              capsys)
    assert code == 0 and "rank-deficient" in codes
    pred = json.loads(out)["predicted_error"]
    assert pred["bounded"] is False and pred["calibration_mean"] is None
    code, out, _, _ = run(["calibrate", "irb120", corpus["onejoint"]], corpus, capsys)
    assert code == 0 and "model uncertainty left: not bounded" in out


def test_free_all_on_irb120_text_and_json_agree(corpus, capsys):
    _, out, _, _ = run(["calibrate", "irb120", corpus["clean"], "--free", "all", "--json"],
                       corpus, capsys)
    result = json.loads(out)
    null = sorted(n for n, p in result["parameters"].items() if p["std"] is None)
    assert {"d3", "alpha6"} <= set(null) and null == sorted(result["unidentifiable"])
    assert all(result["parameters"][n]["free"] for n in null)
    _, text, _, _ = run(["calibrate", "irb120", corpus["clean"], "--free", "all"], corpus, capsys)
    line = next(x for x in text.splitlines() if x.startswith("not identifiable (free"))
    assert sorted(line.split(": ", 1)[1].split(", ")) == null
    assert "held at nominal" not in text


def test_clean_inputs_are_silent(corpus, capsys):
    for argv in (["calibrate", "irb120", corpus["clean"], "--validate", corpus["val"]],
                 ["stewart", "calibrate", "liu2008-cmm", corpus["st_clean"]],
                 ["fk", "puma560", corpus["puma"], "--params", corpus["puma_result"]],
                 ["identifiability", "irb120", "--data", corpus["clean"]],
                 ["simulate", "irb120", "--poses", "5", "--errors", corpus["truth"], "--out",
                  corpus["dir"] + "/sim.csv", "--quiet"],
                 ["handeye", "handeye-camodocal"]):
        code, _, codes, errors = run(argv, corpus, capsys)
        assert code == 0 and codes == [] and errors == [], (argv, codes, errors)
