"""``kinecal demo`` end to end on the bundled UR5 laser-tracker data, and ``kinecal bench``'s
error when there is no source checkout."""

import json
import struct

import numpy as np

import kinecal
from kinecal.cli import main
from kinecal.io.measurements import read_measurements


def test_demo_writes_everything_and_the_calibrated_model_round_trips(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quiet"]) == 0
    stdout = capsys.readouterr().out
    names = {"result.json", "ur5-calibrated.yaml", "report.html", "errors.png",
             "validation.png", "sorted.png", "histogram.png", "convergence.png", "compensated.csv",
             "error-model.json", "ur5-calibrated-auto.yaml", "report-error-model.html"}
    assert {p.name for p in out.iterdir()} == names
    for name in names:
        assert str(out / name) in stdout
    assert "report.html in a browser" in stdout
    # the demo ends by compensating the held-out poses: ~2.6 mm corrections, all converged
    assert "compensation of the 20 held-out poses" in stdout and "20 of 20 converged" in stdout
    comp = np.genfromtxt(out / "compensated.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")
    assert len(comp) == 20 and 2.0 < comp["correction"].mean() < 3.5
    res = json.loads((out / "result.json").read_text(encoding="utf-8"))
    assert res["model"] == "ur5" and res["calibration"]["n"] == 1000
    assert res["validation"]["n"] == 20
    before, after = res["validation"]["before"], res["validation"]["after"]
    # the laser-tracker UR5: about 2.6 mm before, about 0.1 mm after on held-out poses
    assert 2.0 < before["mean"] < 3.5
    assert after["mean"] < 0.15 and after["mean"] < before["mean"] / 10
    # the printed table carries the same numbers
    assert f"{after['mean']:10.4g}" in stdout and f"{before['max']:10.4g}" in stdout
    # the calibrated model file reproduces the validation errors of the result
    model = kinecal.load_model(out / "ur5-calibrated.yaml")
    val = read_measurements("ur5-laser-tracker:random", model)
    d = np.linalg.norm(model.positions(val.q) - val.xyz, axis=1)
    np.testing.assert_allclose(d.mean(), after["mean"], rtol=1e-6)
    np.testing.assert_allclose(d.max(), after["max"], rtol=1e-6)
    # the step beyond geometry: auto below the geometric calibration on the held-out poses
    auto = json.loads((out / "error-model.json").read_text(encoding="utf-8"))
    em = auto["error_model"]
    assert em["geometric"]["validation_mean"] == after["mean"]
    assert auto["validation"]["after"]["mean"] <= 0.090 and em["selected"] in stdout
    assert f"validation mean: geometric {after['mean']:.4g} mm" in stdout
    html = (out / "report-error-model.html").read_text(encoding="utf-8")
    assert 'id="error-model"' in html and 'id="fig-residual-maps"' in html
    html = (out / "report.html").read_text(encoding="utf-8")
    assert html.count("data:image/png;base64,") == 5 and "ur5-laser-tracker:grid" in html
    # the record names the command and the bundled inputs with their SHA-256 (it said
    # "Python API (no command line)" and "No input file recorded")
    from kinecal.io.bundled import input_file
    from kinecal.report.provenance import file_sha256

    for page in ("report.html", "report-error-model.html"):
        text = (out / page).read_text(encoding="utf-8")
        assert "No input file recorded" not in text and "Python API" not in text
        assert "kinecal demo --out" in text
        assert file_sha256(input_file("ur5-laser-tracker:grid")) in text
    for png in ("errors.png", "convergence.png"):
        data = (out / png).read_bytes()
        assert struct.unpack(">II", data[16:24]) == (720, 320)


def test_bench_without_a_source_checkout_is_a_clear_input_error(tmp_path, capsys,
                                                                  monkeypatch):
    monkeypatch.chdir(tmp_path)
    fake = tmp_path / "site-packages" / "kinecal" / "__init__.py"
    monkeypatch.setattr(kinecal, "__file__", str(fake))
    assert main(["bench", "--quick"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "source checkout" in err
