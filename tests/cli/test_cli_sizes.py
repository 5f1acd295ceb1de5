"""Absurd but finite noise levels and error amplitudes are refused against the machine's
size (kinecal.calibration.diagnostics.sizes): exit 2 naming the option, nothing written;
values up to the size pass."""

import json

import numpy as np
import pytest

import kinecal
from kinecal.calibration.diagnostics.sizes import serial_size, stewart_size
from kinecal.calibration.serial.simulate import simulate
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.geometry import load_geometry


def test_machine_sizes():
    assert serial_size(kinecal.load_model("irb120")) == pytest.approx(1004.0, abs=1.0)
    # the paper-004 CMM: the longest leg (0.97 m) is its largest dimension
    assert stewart_size(load_geometry("liu2008-cmm")) == pytest.approx(0.97)


@pytest.mark.parametrize("args, option", [
    (["--noise-position", "1e300"], "--noise-position"),
    (["--noise-position", "1.5"], "--noise-position"),  # 1.5 m on a 0.97 m machine
    (["--noise-legs", "1e300"], "--noise-legs"),
    (["--noise-rotation", "1e12"], "--noise-rotation"),  # arcsec
    (["--errors", "1e300"], "--errors"),
    (["--errors", "2"], "--errors"),
])
def test_stewart_simulate_refuses_values_beyond_the_machine(tmp_path, capsys, args, option):
    out = tmp_path / "s.csv"
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "5", "--out", str(out),
                 *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"kinecal: error: option {option}: ") and "\n" not in err
    assert ("larger than the whole machine (0.97 m)" in err) or ("more than 1 rad" in err)
    assert not out.exists()


def test_stewart_simulate_accepts_noise_up_to_the_machine(tmp_path):
    out = tmp_path / "s.csv"
    assert main(["stewart", "simulate", "liu2008-cmm", "--poses", "5", "--out", str(out),
                 "--noise-position", "0.5", "--noise-rotation", "200000"]) == 0
    assert out.exists()


@pytest.mark.parametrize("args, option", [
    (["--noise", "1e300"], "--noise"),
    (["--noise", "5000"], "--noise"),  # 5 m on an arm of 1 m
    (["--orientation", "--angle-noise", "100"], "--angle-noise"),  # deg
])
def test_simulate_refuses_values_beyond_the_machine(tmp_path, capsys, args, option):
    out = tmp_path / "d.csv"
    assert main(["simulate", "irb120", "--poses", "5", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert f"option {option}:" in err and not out.exists()


def test_truth_file_deviations_beyond_the_machine(tmp_path, capsys):
    truth = tmp_path / "t.json"
    assert main(["simulate", "irb120", "--poses", "5", "--out", str(tmp_path / "d.csv"),
                 "--truth-out", str(truth), "--quiet"]) == 0
    doc = json.loads(truth.read_text())
    for name, value, words in (("d1", 1e300, "more than the whole machine"),
                               ("alpha1", 1e5, "more than half a turn")):
        bad = json.loads(truth.read_text())
        bad["errors"][name] = value
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(bad))
        assert main(["simulate", "irb120", "--poses", "5", "--errors", str(path),
                     "--out", str(tmp_path / "x.csv")]) == 2
        err = capsys.readouterr().err
        assert f"{name} deviates by" in err and words in err and "option --errors" in err
    assert doc["errors"]  # the file's own deviations pass (above)


def test_python_api_refuses_them_too():
    m = kinecal.load_model("irb120")
    for kw in ({"noise": 1e300}, {"orientation": True, "angle_noise": 2.0},
               {"errors": {"d1": 2000.0}}):
        with pytest.raises(InputError):
            simulate(m, 3, rng=0, **kw)
    ok = simulate(m, 3, rng=0, noise=1000.0)  # noisy, but not beyond the machine
    assert np.isfinite(ok.data.xyz).all()


@pytest.mark.parametrize("tolerances, words", [("{length: 1e200, angle: 2.86}", "length tolerance"),
                                               ("{length: 0.25, angle: 1e5}", "angle tolerance")])
def test_tolerances_beyond_the_machine_are_refused(tmp_path, capsys, tolerances, words):
    """A metaheuristic searched a 1e200 mm box (internal error, exit 1); simulate drew
    errors from it."""
    from kinecal.io.models import model_path

    text = model_path("irb120").read_text()
    path = tmp_path / "wide.yaml"
    path.write_text("\n".join(f"tolerances: {tolerances}" if ln.startswith("tolerances:")
                              else ln for ln in text.splitlines()) + "\n")
    data = tmp_path / "d.csv"
    assert main(["simulate", "irb120", "--poses", "30", "--out", str(data), "--quiet"]) == 0
    for args in (["simulate", str(path), "--poses", "5", "--out", str(tmp_path / "x.csv")],
                 ["calibrate", str(path), str(data), "--method", "pso", "--maxiter", "2"],
                 ["calibrate", str(path), str(data)]):
        assert main(args) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
