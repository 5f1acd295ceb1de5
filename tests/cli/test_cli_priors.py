"""``kinecal calibrate --prior / --prior-from``: the result JSON's ``prior`` and ``free``,
the forms of the option (groups, file, auto, a previous result), several kinds of files,
and bad input: exit 2 with one line, nothing written."""

import json

import numpy as np
import pytest

import kinecal
from kinecal.cli import main


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("priors")
    assert main(["simulate", "irb120", "--poses", "30", "--noise", "1", "--seed", "4",
                 "--out", str(d / "meas.csv")]) == 0
    return d


def _result(d, *args):
    out = d / "r.json"
    if out.exists():
        out.unlink()
    assert main(["calibrate", "irb120", str(d / "meas.csv"), "--quiet", "--out", str(out),
                 *args]) == 0
    return json.loads(out.read_text())


def test_no_prior_is_the_default_and_says_so(data):
    r = _result(data)
    assert r["prior"] is None and isinstance(r["free"], list)


def test_groups_in_model_units(data):
    r = _result(data, "--prior", "lengths=0.25,angles=2")
    p = r["prior"]
    assert p["kind"] == "groups" and p["used"] == "lengths=0.25,angles=2"
    assert set(p["sigma"]) == set(r["free"])  # every free parameter of the arm
    assert p["sigma"]["d1"] == pytest.approx(0.25)
    assert p["sigma"]["alpha1"] == pytest.approx(2.0)  # degrees, as the model file
    assert p["noise_source"] == "estimated" and p["noise"] > 0
    assert p["directions"]["data"] + p["directions"]["prior"] == len(r["free"])
    assert set(p["data_share"]) == set(r["free"])
    assert all(r["parameters"][n]["std"] is not None for n in r["free"])


def test_auto_reports_the_chosen_strength(data):
    r = _result(data, "--prior", "auto", "--free", "all")
    p = r["prior"]
    assert p["kind"] == "auto" and p["given"] == "auto"
    assert p["strength"] is None or p["strength"] > 0
    chosen = p["cross_validation"]["chosen"]
    assert chosen == p["strength"]
    means = {c["strength"]: c["mean"] for c in p["cross_validation"]["candidates"]}
    assert means[chosen] == min(means.values())
    if chosen is not None:
        m = kinecal.load_model("irb120")
        assert p["used"] == (f"lengths={chosen * m.tolerances['length']:.4g},"
                             f"angles={chosen * np.degrees(m.tolerances['angle']):.4g}")


def test_file_and_previous_result(data):
    first = _result(data)
    (data / "first.json").write_text(json.dumps(first))
    (data / "prior.csv").write_text("name,sigma,mean\nd1,1e-6,\na2,0.1,270.5\n")
    r = _result(data, "--prior", str(data / "prior.csv"), "--prior-from",
                str(data / "first.json"))
    p = r["prior"]
    assert p["kind"] == "file" and p["mean"] == str(data / "first.json")
    assert set(p["sigma"]) <= {"d1", "a2"}
    # d1 held to the previous result's value, a2 pulled towards its stated mean
    assert r["parameters"]["d1"]["identified"] == pytest.approx(
        first["parameters"]["d1"]["identified"], abs=1e-4)


def test_prior_from_alone_means_auto(data):
    (data / "first.json").write_text(json.dumps(_result(data)))
    r = _result(data, "--prior-from", str(data / "first.json"))
    assert r["prior"]["kind"] == "auto"


def test_several_kinds_take_the_prior(tmp_path):
    assert main(["simulate", "ur5", "--kind", "plane", "--poses", "25", "--groups", "3",
                 "--noise", "0.05", "--seed", "2", "--out", str(tmp_path / "p.csv")]) == 0
    assert main(["calibrate", "ur5", str(tmp_path / "p.csv"), "--quiet", "--out",
                 str(tmp_path / "r.json"), "--prior", "lengths=1,angles=0.5"]) == 0
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["prior"]["used"] == "lengths=1,angles=0.5" and r["kinds"]


@pytest.mark.parametrize("args, words", [
    (["--prior", "lenghts=0.5"], "unknown group 'lenghts'"),
    (["--prior", "lengths=-1"], "positive"),
    (["--prior", "nofile.csv"], "no such file"),
    (["--prior", "auto", "--method", "pso"], "--method lm"),
    (["--prior", "auto", "--loss", "huber"], "--loss linear"),
    (["--prior", "auto", "--error-model", "compliance"], "joint-error"),
])
def test_bad_prior_exits_2_and_writes_nothing(data, capsys, args, words):
    out = data / "bad.json"
    code = main(["calibrate", "irb120", str(data / "meas.csv"), "--quiet", "--out",
                 str(out), *args])
    err = capsys.readouterr().err
    assert code == 2 and words in err and "--prior" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def test_bad_prior_file_names_its_row(data, capsys):
    (data / "bad.csv").write_text("name,sigma\nd1,0.5\ntheta9,0.1\n")
    code = main(["calibrate", "irb120", str(data / "meas.csv"), "--quiet", "--prior",
                 str(data / "bad.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "bad.csv, row 2" in err and "theta9" in err


def test_prior_file_is_never_overwritten(data, capsys):
    (data / "keep.csv").write_text("name,sigma\nd1,0.5\n")
    code = main(["calibrate", "irb120", str(data / "meas.csv"), "--quiet", "--prior",
                 str(data / "keep.csv"), "--out", str(data / "keep.csv")])
    assert code == 2 and (data / "keep.csv").read_text() == "name,sigma\nd1,0.5\n"
