"""``kinecal export`` and URDF models on the command line (--base-link, --tip-link)."""

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import kinecal
from kinecal.cli import main
from kinecal.io.measurements import read_measurements
from kinecal.io.models import load_model
from kinecal.io.result_values import parameters_from_result
from kinecal.io.urdf import load_urdf

IRB140 = resources.files("rtbdata") / "xacro" / "abb_irb140_description/urdf/irb140.urdf"


def _pin_tool(path, q):
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    fid = model.getFrameId("tool")
    out = []
    for qi in q:
        pin.framesForwardKinematics(model, data, qi)
        out.append(data.oMf[fid].translation.copy())
    return np.array(out)


def test_calibrate_export_urdf_and_yaml_from_result(tmp_path, capsys):
    result = tmp_path / "result.json"
    assert main(["calibrate", "ur5", "ur5-laser-tracker:grid", "--out", str(result),
                 "--quiet"]) == 0
    urdf, yaml = tmp_path / "ur5-cal.urdf", tmp_path / "ur5-cal.yaml"
    assert main(["export", str(result), "--out", str(urdf)]) == 0
    assert main(["export", str(result), "--format", "yaml", "--out", str(yaml)]) == 0
    err = capsys.readouterr().err
    assert "metres, radians" in err and "calibrated ur5" in err
    model = load_model("ur5")
    params = parameters_from_result(model, result)
    q = read_measurements("ur5-laser-tracker:random", model).q
    mine = model.positions(q, params)
    assert np.abs(_pin_tool(urdf, q) * 1000.0 - mine).max() <= 1e-9
    np.testing.assert_allclose(load_model(yaml).positions(q), mine, rtol=0, atol=1e-9)
    np.testing.assert_allclose(load_urdf(urdf).positions(q) * 1000.0, mine, rtol=0, atol=1e-9)


def test_urdf_model_through_simulate_identifiability_calibrate_fk(tmp_path, capsys):
    sim, truth = tmp_path / "sim.csv", tmp_path / "truth.json"
    common = ["--base-link", "base_link", "--tip-link", "tool0"]
    assert main(["simulate", str(IRB140), *common, "--poses", "60", "--seed", "3",
                 "--out", str(sim), "--truth-out", str(truth)]) == 0
    header = sim.read_text().splitlines()[0]
    assert header.startswith("q1,q2,q3,q4,q5,q6,x,y,z")
    assert main(["identifiability", str(IRB140), *common, "--data", str(sim), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["n_parameters"] == 51 and report["rank"] >= 25
    out = tmp_path / "r.json"
    assert main(["calibrate", str(IRB140), str(sim), *common, "--out", str(out), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["calibration"]["after"]["max"] < 1e-9  # metres, noise-free
    assert res["length_unit"] == "m" and res["angle_unit"] == "deg"
    cal = tmp_path / "irb140-cal.urdf"
    assert main(["export", str(out), "--nominal", str(IRB140), "--out", str(cal)]) == 0
    assert cal.read_text().count("<visual>") == 7  # written into a copy of the source URDF
    bare = tmp_path / "irb140-chain.urdf"
    assert main(["export", str(out), "--nominal", str(IRB140), "--out", str(bare),
                 "--chain-only"]) == 0
    assert "<visual>" not in bare.read_text()
    assert main(["fk", str(cal), str(sim)]) == 0
    xyz = np.loadtxt(capsys.readouterr().out.splitlines(), delimiter=",", skiprows=1)
    measured = np.loadtxt(sim, delimiter=",", skiprows=1)[:, 6:9]
    assert np.abs(xyz - measured).max() < 1e-8  # fk prints 10 significant digits


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["fk", "ur5", "ur5-laser-tracker:random", "--tip-link", "tool0"], "URDF models only"),
        (["fk", str(IRB140), "ur5-laser-tracker:random", "--tip-link", "nope"], "no link"),
        (["export", "ur5", "--out", "OUT/x.txt"], "cannot tell the format"),
        (["export", "ur5", "--out", "OUT/x.urdf", "--format", "sdf"], "unknown format"),
        (["export", "ur5", "--out", "OUT/x.urdf", "--nominal", "ur5"], "RESULT.json"),
        (["export", "OUT/r.json", "--out", "OUT/r.json", "--format", "urdf"], "overwrite"),
        (["export", "OUT/r.json", "--out", "OUT/x.urdf"], "not a bundled one"),
        (["export", "OUT/r.json", "--out", "OUT/x.urdf", "--nominal", "puma560"],
         "nominal value"),
    ],
)
def test_export_and_link_option_errors(tmp_path, capsys, args, match):
    (tmp_path / "r.json").write_text(json.dumps(
        {"model": "mine", "parameters": {"d1": {"nominal": 89.159, "identified": 89.2}}}))
    args = [a.replace("OUT", str(tmp_path)) for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and match in err, err


def test_export_warns_and_strict_refuses(tmp_path, capsys):
    urdf = tmp_path / "nolimit.urdf"
    urdf.write_text("<robot name='x'><link name='a'/><link name='b'/><joint name='j' "
                    "type='revolute'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/>"
                    "<limit effort='1' velocity='1'/></joint></robot>")
    assert main(["export", str(urdf), "--out", str(tmp_path / "x.yaml")]) == 0
    assert "warning" in capsys.readouterr().err and (tmp_path / "x.yaml").exists()
    assert main(["export", str(urdf), "--out", str(tmp_path / "y.yaml"), "--strict"]) == 2
    assert "urdf-joint-limits" in capsys.readouterr().err
    assert not (tmp_path / "y.yaml").exists()


def test_a_stewart_geometry_is_named_as_such_with_what_export_takes(tmp_path, capsys):
    """``export liu2008-cmm`` said "not a bundled model": it is a bundled Stewart geometry
    (bundled or as a file); other commands name the kind too."""
    geometry = tmp_path / "g.yaml"
    geometry.write_bytes((Path(kinecal.__file__).parent / "robots" / "liu2008-cmm.yaml")
                         .read_bytes())
    for source in ("liu2008-cmm", str(geometry)):
        assert main(["export", source, "--out", str(tmp_path / "x.urdf")]) == 2
        err = capsys.readouterr().err
        assert f"{source} is a Stewart-platform geometry: export writes serial arms (a " \
               "model: bundled name, YAML or URDF; or a calibration result JSON" in err
        assert "stewart calibrate --geometry-out" in err and err.count("\n") == 1
    assert not list(tmp_path.glob("x.*"))
    assert main(["fk", "liu2008-cmm", "0,0,0,0,0,0"]) == 2
    assert "'liu2008-cmm' is a bundled Stewart-platform geometry, not a serial-arm model " \
           "(bundled serial-arm models: " in capsys.readouterr().err
    assert main(["stewart", "ik", "ur5", str(geometry)]) == 2
    assert "'ur5' is a bundled serial-arm model, not a Stewart-platform geometry" in \
        capsys.readouterr().err
