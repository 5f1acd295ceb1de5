"""Wide marker tables (x1,y1,z1,x2,... one row per pose, FIGAROH's layout: kinecal.io.wide)
and joints in radians (--angle-unit rad) in every command that reads joints."""

import csv
import json

import numpy as np
import pytest

from kinecal import calibrate, simulate
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.measurements import read_measurements, write_measurements
from kinecal.io.models import load_model, save_model

POINTS = {"A": [0.0, 0.0, 31.0], "B": [52.0, -3.0, 20.0], "C": [-4.0, 61.0, 25.0]}


def _cells(values):
    return [repr(float(v)) for v in values]


def _write(path, header, rows):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return path


@pytest.fixture(scope="module")
def mocap(tmp_path_factory):
    """A UR5 (model file in degrees, no markers) seen by motion capture: 25 poses x 3
    markers, in kinecal's long form (degrees) and as FIGAROH writes it: one row per pose,
    markers side by side, joints by name in radians, extra columns."""
    d = tmp_path_factory.mktemp("wide")
    arm = load_model("ur5")
    truth = arm.with_markers(POINTS)
    sim = simulate(truth, 25, noise=0.3, rng=4)
    write_measurements(d / "long.csv", sim.data, truth)
    q = np.asarray(sim.data.q)[::3]
    xyz = np.asarray(sim.data.xyz).reshape(25, 9)
    names = [f"joint{i}" for i in range(1, 7)]
    header = ["x1", "y1", "z1", "x2", "y2", "z2", "x3", "y3", "z3", *[f"q{i}" for i in
                                                                      range(1, 7)],
              "shipped_row", "marker_std_mm"]
    rows = [[*(repr(float(v)) for v in xyz[i]), *(repr(float(v)) for v in q[i]), str(i), "0.2"]
            for i in range(25)]
    _write(d / "wide.csv", header, rows)
    save_model(arm, d / "arm.yaml")
    return arm, d, sim.data, names


def test_a_wide_table_is_the_long_one(mocap):
    arm, d, _, _ = mocap
    wide = read_measurements(d / "wide.csv", arm, angle_unit="rad")
    long = read_measurements(d / "long.csv", arm)
    assert wide.marker_names == ("1", "2", "3")
    np.testing.assert_array_equal(wide.marker, long.marker)
    np.testing.assert_array_equal(wide.xyz, long.xyz)
    np.testing.assert_allclose(wide.q, long.q, rtol=0, atol=1e-12)
    # a model that declares markers: wide marker i is its i-th
    named = read_measurements(d / "wide.csv", arm.with_markers(POINTS), angle_unit="rad")
    assert named.marker_names == ("A", "B", "C")


def test_calibrate_from_the_wide_table_in_radians(mocap, capsys):
    arm, d, _, _ = mocap
    assert main(["calibrate", str(d / "arm.yaml"), str(d / "wide.csv"), "--angle-unit", "rad",
                 "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    ref = calibrate(arm, read_measurements(d / "long.csv", arm))  # markers A, B, C
    named = {f"tool.{i}.{c}": f"tool.{m}.{c}" for i, m in zip("123", "ABC", strict=True)
             for c in "xyz"}
    assert [named.get(n, n) for n in res["free"]] == ref.free
    mine = {named.get(n, n): v["identified"] for n, v in res["parameters"].items()}
    theirs = ref.to_dict()["parameters"]  # model units, as the JSON
    np.testing.assert_allclose([mine[n] for n in ref.free],
                               [theirs[n]["identified"] for n in ref.free], rtol=0, atol=1e-6)
    # in degrees (the model's unit) the same radians are a wrong unit: warned, not silent
    assert main(["calibrate", str(d / "arm.yaml"), str(d / "wide.csv"), "--json"]) == 0
    codes = {w["code"] for w in json.loads(capsys.readouterr().out)["warnings"]}
    assert "joint-units" in codes


def test_occluded_markers_leave_their_row_out(tmp_path):
    arm = load_model("ur5")
    header = ["q1", "q2", "q3", "q4", "q5", "q6", "x1", "y1", "z1", "x2", "y2", "z2"]
    _write(tmp_path / "w.csv", header, [["0"] * 6 + ["1", "2", "3", "", "", ""],
                                        ["10"] * 6 + ["4", "5", "6", "7", "8", "9"]])
    m = read_measurements(tmp_path / "w.csv", arm)
    assert m.marker.tolist() == [0, 0, 1]
    np.testing.assert_array_equal(m.xyz, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])
    np.testing.assert_allclose(m.q[:, 0], np.radians([0, 10, 10]))


@pytest.mark.parametrize("header, row, message", [
    (["x1", "y1", "z1", "x2", "y2"], ["1", "2", "3", "4", "5"],
     "column(s) z2 missing: a wide marker table gives x2,y2,z2 for every marker 1..2"),
    (["x1", "y1", "z1", "x3", "y3", "z3"], ["1"] * 6,
     "column(s) x2, y2, z2 missing"),
    (["x", "y", "z", "x1", "y1", "z1"], ["1"] * 6,
     "column(s) x, y, z beside wide marker columns"),
    (["x1", "y1", "z1", "marker"], ["1", "2", "3", "A"],
     "column(s) marker beside wide marker columns"),
    (["x1", "y1", "z1", "x2", "y2", "z2"], ["1", "2", "3", "4", "", "6"],
     "row 1: column y2: blank where x2, z2 are given"),
    (["x1", "y1", "z1"], ["1", "2", "abc"], "row 1: column z1: 'abc' is not a number"),
    (["x1", "y1", "z1"], ["1", "2", "nan"], "row 1: column z1: 'nan', expected a finite"),
    (["x1", "y1", "z1"], ["", "", ""], "no marker position on any row"),
])
def test_bad_wide_tables_are_named(tmp_path, header, row, message):
    arm = load_model("ur5")
    path = _write(tmp_path / "bad.csv", [f"q{i}" for i in range(1, 7)] + header,
                  [["0"] * 6 + row])
    with pytest.raises(InputError) as exc:
        read_measurements(path, arm)
    assert message in str(exc.value) and "bad.csv" in str(exc.value)


def test_more_wide_markers_than_the_model_declares(tmp_path):
    arm = load_model("ur5").with_markers({"A": [0, 0, 1.0]})
    path = _write(tmp_path / "w.csv", [f"q{i}" for i in range(1, 7)] +
                  ["x1", "y1", "z1", "x2", "y2", "z2"], [["0"] * 12])
    with pytest.raises(InputError, match=r"2 markers .x1..z2., the model declares 1 .A."):
        read_measurements(path, arm)


def test_every_joint_reader_takes_radians(mocap, tmp_path, capsys):
    """fk, identifiability --data, select-poses, simulate --joints, compensate and iso9283
    on joints in radians give what they give on the same joints in degrees."""
    _, d, data, _ = mocap
    model = str(d / "arm.yaml")
    q_deg = np.degrees(np.asarray(data.q)[::3][:8])
    deg = _write(tmp_path / "deg.csv", [f"q{i}" for i in range(1, 7)],
                 [_cells(r) for r in q_deg])
    rad = _write(tmp_path / "rad.csv", [f"q{i}" for i in range(1, 7)],
                 [_cells(r) for r in np.radians(q_deg)])
    outs = []
    for f, unit in ((deg, []), (rad, ["--angle-unit", "rad"])):
        assert main(["fk", model, str(f), *unit]) == 0
        outs.append(np.loadtxt(capsys.readouterr().out.splitlines()[1:], delimiter=","))
    np.testing.assert_allclose(outs[0], outs[1], rtol=0, atol=1e-9)
    for f, unit in ((deg, []), (rad, ["--angle-unit", "rad"])):
        assert main(["identifiability", model, "--data", str(f), *unit, "--json"]) == 0
        outs.append(json.loads(capsys.readouterr().out)["identifiable"])
    assert outs[2] == outs[3]
    # select-poses writes the plan in the unit asked for
    for name, unit in (("p_deg.csv", []), ("p_rad.csv", ["--angle-unit", "rad"])):
        assert main(["select-poses", model, "--count", "10", "--candidates", "200", "--out",
                     str(tmp_path / name), *unit]) == 0
    a = np.loadtxt(tmp_path / "p_deg.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(tmp_path / "p_rad.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(np.radians(a), b, rtol=1e-12)
    # simulate --joints: the input in radians, the output in the model's degrees
    for f, name, unit in ((deg, "s_deg.csv", []), (rad, "s_rad.csv", ["--angle-unit", "rad"])):
        assert main(["simulate", model, "--joints", str(f), "--errors", "zero", "--out",
                     str(tmp_path / name), "--quiet", *unit]) == 0
    np.testing.assert_allclose(np.loadtxt(tmp_path / "s_deg.csv", delimiter=",", skiprows=1),
                               np.loadtxt(tmp_path / "s_rad.csv", delimiter=",", skiprows=1),
                               rtol=0, atol=1e-9)
    capsys.readouterr()
    assert main(["fk", model, str(deg), "--angle-unit", "grad"]) == 2
    assert "--angle-unit" in capsys.readouterr().err


def test_compensate_and_iso9283_in_radians(mocap, tmp_path, capsys):
    arm, d, data, _ = mocap
    model = str(d / "arm.yaml")
    assert main(["calibrate", model, str(d / "long.csv"), "--model-out",
                 str(tmp_path / "cal.yaml"), "--quiet"]) == 0
    q = np.degrees(np.asarray(data.q)[::3][:6])
    for unit, scale, extra in (("deg", 1.0, []), ("rad", np.pi / 180, ["--angle-unit", "rad"])):
        prog = _write(tmp_path / f"prog_{unit}.csv", [f"q{i}" for i in range(1, 7)],
                      [_cells(r * scale) for r in q])
        assert main(["compensate", str(tmp_path / "cal.yaml"), str(prog), "--nominal",
                     model, "--tool", "nominal", "--out", str(tmp_path / f"out_{unit}.csv"),
                     "--quiet",
                     *extra]) == 0
    with open(tmp_path / "out_deg.csv") as a, open(tmp_path / "out_rad.csv") as b:
        ra, rb = list(csv.DictReader(a)), list(csv.DictReader(b))
    for x, y in zip(ra, rb, strict=True):
        for c in ("q1", "q6", "dq2"):
            assert abs(np.radians(float(x[c])) - float(y[c])) < 1e-9
        assert abs(float(x["correction"]) - float(y["correction"])) < 1e-9
    # iso9283 with --model: commanded poses from joints in radians
    rows = [[f"P{p}", str(c), "0", "0", "0", *_cells(np.radians(q[p]))]
            for p in range(3) for c in range(1, 4)]
    path = _write(tmp_path / "iso.csv", ["pose", "cycle", "x", "y", "z",
                                         *[f"q{i}" for i in range(1, 7)]], rows)
    assert main(["iso9283", str(path), "--model", model, "--angle-unit", "rad",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    P = arm.positions(np.radians(q[:3]))
    assert abs(out["poses"][0]["AP"] - np.linalg.norm(P[0])) < 1e-6
