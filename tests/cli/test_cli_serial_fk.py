"""``kinecal models`` and ``kinecal fk``."""

import json

import numpy as np

import kinecal
from kinecal.cli import main


def test_models_json(capsys):
    assert main(["models", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    names = [m["name"] for m in data["models"]]
    assert "irb120" in names and "ur5" in names
    assert any(d["name"] == "ur5-laser-tracker" for d in data["datasets"])


def test_fk_matches_api(tmp_path, capsys):
    model = kinecal.load_model("irb120")
    rng = np.random.default_rng(1)
    q = rng.uniform(-1, 1, (4, 6))
    csv = tmp_path / "joints.csv"
    csv.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(
        ",".join(repr(float(v)) for v in np.rad2deg(row)) for row in q) + "\n")
    assert main(["fk", "irb120", str(csv), "--pose"]) == 0
    out = np.loadtxt(capsys.readouterr().out.splitlines(), delimiter=",", skiprows=1)
    T = model.fk(q)
    np.testing.assert_allclose(out[:, :3], T[:, :3, 3], atol=1e-6)
    assert out.shape == (4, 7)


def test_fk_params_from_result(tmp_path, capsys):
    csv = tmp_path / "joints.csv"
    csv.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,0,0\n")
    res = tmp_path / "r.json"
    res.write_text(json.dumps({"parameters": {"d1": {"identified": 300.0}}}))
    assert main(["fk", "irb120", str(csv), "--params", str(res)]) == 0
    z_cal = float(capsys.readouterr().out.splitlines()[1].split(",")[2])
    assert main(["fk", "irb120", str(csv)]) == 0
    z_nom = float(capsys.readouterr().out.splitlines()[1].split(",")[2])
    assert abs(z_cal - z_nom - 10.0) < 1e-6


def test_fk_bad_input_exit_2(tmp_path, capsys):
    csv = tmp_path / "joints.csv"
    csv.write_text("q1,q2,q3\n0,0,0\n")
    assert main(["fk", "irb120", str(csv)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "q4" in err and "joints.csv" in err


def test_ctrl_c_is_one_line_and_exit_130(capsys):
    from kinecal.cli._app import app

    @app.command("interrupt-me", hidden=True)
    def interrupt_me() -> None:
        raise KeyboardInterrupt

    assert main(["interrupt-me"]) == 130
    assert capsys.readouterr().err == "kinecal: interrupted\n"
