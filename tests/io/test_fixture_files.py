"""Known fixtures in files: px,py,pz[,nx,ny,nz] columns of point and plane files and
--fixture files (kinecal.io.fixtures), bad input named by file, row and column, and the
command line."""

import dataclasses
import json

import numpy as np
import pytest

from kinecal.calibration.blocks.simulate import simulate_kind
from kinecal.calibration.serial.simulate import random_errors
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.csvtable import write_table
from kinecal.io.fixtures import read_fixture, with_fixture
from kinecal.io.kinds import read_gauge, write_gauge
from kinecal.io.models import load_model, save_model
from kinecal.kinematics.serial.model import SerialModel

PLANES = np.array([[350.0, 0, 200, 1, 0, 0], [200, 150, 200, 0, 1, 0], [200, 0, 100, 0, 0, 1]])
COLS = ["px", "py", "pz", "nx", "ny", "nz"]


def mate():
    joints = [dict(theta=0.0, d=300.0, a=50.0, alpha=np.pi / 2),
              dict(theta=0.0, d=0.0, a=250.0, alpha=0.0),
              dict(theta=0.0, d=0.0, a=200.0, alpha=0.0)]
    return SerialModel("mate", "dh", joints, base=[0.0] * 6, tool=[30.0, 10.0, 20.0],
                       joint_limits=[[-2.5, 2.5]] * 3,
                       tolerances={"length": 0.5, "angle": 0.005})


@pytest.fixture(scope="module")
def planes(tmp_path_factory):
    d = tmp_path_factory.mktemp("fixtures")
    m = mate()
    truth = m.nominal + random_errors(m, np.random.default_rng(1))
    sim = simulate_kind(m, "plane", 20, true_params=truth, planes=PLANES, rng=2, noise=0.002)
    save_model(m, d / "mate.yaml")
    write_gauge(d / "planes.csv", sim.data, m)
    write_table(d / "fixture.csv", {"plane": np.array(["F1", "F2", "F3"], dtype=object),
                                    **{c: PLANES[:, k] for k, c in enumerate(COLS)}})
    return m, d, sim.data


def _lines(path):
    return path.read_text().splitlines()


def _with_columns(path, out, cells):
    """`path` with the known columns appended, `cells(row index, group id)` -> 6 strings."""
    lines = _lines(path)
    text = [lines[0] + "," + ",".join(COLS)]
    for i, line in enumerate(lines[1:]):
        text.append(line + "," + ",".join(cells(i, line.rsplit(",", 1)[1])))
    out.write_text("\n".join(text) + "\n")


def test_known_columns_round_trip_with_unknown_ids_blank(planes, tmp_path):
    m, _, data = planes
    known = PLANES.copy()
    known[1] = np.nan  # F2 solved with the arm
    mixed = dataclasses.replace(data, known=known)
    write_gauge(tmp_path / "mixed.csv", mixed, m)
    back = read_gauge(tmp_path / "mixed.csv", m)
    np.testing.assert_array_equal(back.known_groups, [True, False, True])
    np.testing.assert_array_equal(back.known[[0, 2]], PLANES[[0, 2]])
    assert "F2,,,,,," in (tmp_path / "mixed.csv").read_text()


def test_a_normal_of_any_length_is_normalised(planes, tmp_path):
    m, d, _ = planes
    _with_columns(d / "planes.csv", tmp_path / "p.csv", lambda i, g: (
        ["350", "0", "200", "2", "0", "0"] if g == "F1" else [""] * 6))
    back = read_gauge(tmp_path / "p.csv", m)
    np.testing.assert_array_equal(back.known[0], [350, 0, 200, 1, 0, 0])
    assert back.known_groups.tolist() == [True, False, False]


@pytest.mark.parametrize("cells, message", [
    (lambda i, g: ["350", "", "200", "1", "0", "0"] if i == 3 else [""] * 6,
     "row 4: column py: blank where px, pz, nx, ny, nz are given"),
    (lambda i, g: ["350", "0", "200", "0", "0", "0"] if i == 0 else [""] * 6,
     "row 1: columns nx,ny,nz: a zero normal"),
    (lambda i, g: ["350", "0", "2e9x", "1", "0", "0"] if i == 0 else [""] * 6,
     "row 1: column pz: '2e9x' is not a number"),
    (lambda i, g: [str(350 + i), "0", "200", "1", "0", "0"] if g == "F1" else [""] * 6,
     "row 2: plane 'F1': px,py,pz,nx,ny,nz differ from row 1's"),
])
def test_bad_known_cells_are_named(planes, tmp_path, cells, message):
    m, d, _ = planes
    _with_columns(d / "planes.csv", tmp_path / "p.csv", cells)
    with pytest.raises(InputError) as exc:
        read_gauge(tmp_path / "p.csv", m)
    assert message in str(exc.value) and "p.csv" in str(exc.value)


def test_columns_of_another_kind_or_only_some_are_refused(tmp_path):
    m = load_model("irb120")
    (tmp_path / "pt.csv").write_text("q1,q2,q3,q4,q5,q6,point,px,py,pz,nx\n"
                                     "0,0,0,0,0,0,P1,1,2,3,0\n")
    with pytest.raises(InputError, match=r"column.s. nx: a point file gives px,py,pz"):
        read_gauge(tmp_path / "pt.csv", m)
    (tmp_path / "pl.csv").write_text("q1,q2,q3,q4,q5,q6,plane,px,py,pz\n0,0,0,0,0,0,F,1,2,3\n")
    with pytest.raises(InputError, match=r"column.s. nx, ny, nz missing: a known plane"):
        read_gauge(tmp_path / "pl.csv", m)
    (tmp_path / "bb.csv").write_text("q1,q2,q3,q4,q5,q6,pivot,distance,px\n"
                                     "0,0,0,0,0,0,P,100,1\n")
    with pytest.raises(InputError, match="ballbar files have no known geometry"):
        read_gauge(tmp_path / "bb.csv", m)


def test_fixture_files(planes, tmp_path):
    _, d, data = planes
    fix = read_fixture(d / "fixture.csv")
    assert fix.kind == "plane" and list(fix.values) == ["F1", "F2", "F3"]
    assert with_fixture(data, [fix]).known_groups.all()
    # the same id in the measurement file with other values: which one is right?
    other = dataclasses.replace(data, known=PLANES + [[1.0, 0, 0, 0, 0, 0]] * 3)
    with pytest.raises(InputError, match=r"F1.*the fixture gives other coordinates"):
        with_fixture(other, [fix])
    (tmp_path / "twice.csv").write_text("point,px,py,pz\nA,1,2,3\nA,1,2,4\n")
    with pytest.raises(InputError, match="row 2: point 'A' is given twice"):
        read_fixture(tmp_path / "twice.csv")
    (tmp_path / "none.csv").write_text("id,px,py,pz\nA,1,2,3\n")
    with pytest.raises(InputError, match="one id column, point or plane"):
        read_fixture(tmp_path / "none.csv")
    (tmp_path / "blank.csv").write_text("point,px,py,pz\nA,,,\n")
    with pytest.raises(InputError, match="row 1: point 'A': no px,py,pz"):
        read_fixture(tmp_path / "blank.csv")


def test_command_line(planes, tmp_path, capsys):
    d = planes[1]
    model, data, fixture = (str(d / n) for n in ("mate.yaml", "planes.csv", "fixture.csv"))
    assert main(["identifiability", model, "--data", data, "--fixture", fixture,
                 "--json"]) == 0
    ident = json.loads(capsys.readouterr().out)
    assert ident["fixtures_show"] == ["translation", "rotation"]
    assert ident["not_seen"] == ["scale about (350, 150, 100)"]
    assert ident["kinds"][0]["known"] == 3 and ident["kinds"][0]["unknowns"] == 0
    assert main(["calibrate", model, data, "--fixture", fixture, "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["free"] == ident["identifiable"]
    assert main(["calibrate", model, data, "--fixture", fixture]) == 0
    assert ("known fixtures make visible: the base frame (where the arm stands: translation "
            "and rotation)") in capsys.readouterr().out
    # a fixture of ids no file touches, or without a point or plane file, is refused
    (tmp_path / "other.csv").write_text("plane,px,py,pz,nx,ny,nz\nG1,0,0,0,0,0,1\n")
    assert main(["calibrate", model, data, "--fixture", str(tmp_path / "other.csv")]) == 2
    assert "none of its planes (G1) is touched" in capsys.readouterr().err
    assert main(["identifiability", model, "--fixture", fixture]) == 2
    assert "--fixture" in capsys.readouterr().err
