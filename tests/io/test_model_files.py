"""Model files: bundled models, round trips, schema errors."""

import numpy as np
import pytest

import kinecal
from kinecal.errors import InputError
from kinecal.io.models import bundled_models, load_model, save_model

PAPER000_NOMINAL_H = [150, 200, 400, 150, 300, 150]


def test_bundled_models_load():
    names = bundled_models()
    for required in ("hu2005-scanner", "irb120", "ur5", "puma560", "kr6-craig"):
        assert required in names
    for name in names:
        m = load_model(name)
        assert m.n_params == len(m.parameter_names)


def test_hu2005_scanner_is_paper000_table1():
    m = load_model("hu2005-scanner")
    p = dict(zip(m.parameter_names, m.nominal, strict=True))
    assert [p[f"d{i}"] for i in range(1, 7)] == PAPER000_NOMINAL_H
    assert [p[f"a{i}"] for i in range(1, 7)] == [0] * 6
    np.testing.assert_allclose(np.rad2deg([p[f"alpha{i}"] for i in range(1, 7)]),
                               [90, -90, 90, -90, 90, -90])
    assert p["tool.z"] == 100


def test_irb120_has_beta2_and_25_parameters():
    m = load_model("irb120")
    assert "beta2" in m.parameter_names and "beta3" not in m.parameter_names
    assert len(m.calibratable) == 25


@pytest.mark.parametrize("name", ["irb120", "ur5", "kr6-craig"])
def test_save_load_round_trip(tmp_path, name):
    m = load_model(name)
    rng = np.random.default_rng(0)
    p = m.nominal + rng.normal(0, 0.01, m.n_params)
    changed = m.with_params(p, name=f"{name}-cal")
    save_model(changed, tmp_path / "m.yaml")
    back = load_model(tmp_path / "m.yaml")
    assert back.name == f"{name}-cal" and back.convention == m.convention
    np.testing.assert_allclose(back.nominal, p, rtol=0, atol=1e-12)
    q = rng.uniform(-1, 1, (5, 6))
    np.testing.assert_allclose(back.fk(q), changed.fk(q), atol=1e-9)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("name: x\nconvention: dh\nangle_unit: deg\njoints: [{d: 1, a: 2}]\n", "alpha"),
        ("name: x\nconvention: foo\nangle_unit: deg\njoints: []\n", "convention"),
        ("name: x\nconvention: dh\nangle_unit: grad\njoints: [{d: 1, a: 2, alpha: 0}]\n",
         "angle_unit"),
        ("name: x\nconvention: dh\nangle_unit: deg\njoints: [{d: 1, a: 2, alpha: 0, beta: 1}]\n",
         "beta"),
        ("name: x\nconvention: dh\nangle_unit: deg\njoints: [{d: 1, a: 2, alpha: 0}]\n"
         "base: [1, 2]\n", "base"),
        ("name: [unclosed\n", "YAML"),
        ("- just\n- a list\n", "mapping"),
        ("name: x\nconvention: dh\nangle_unit: deg\njoints: [{d: 1, a: 2, alpha: 0}]\n"
         "colour: red\n", "colour"),
    ],
)
def test_bad_model_files(tmp_path, text, match):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=match) as info:
        load_model(path)
    assert "bad.yaml" in str(info.value)


def test_unknown_model_name():
    with pytest.raises(InputError, match="bundled"):
        kinecal.load_model("no-such-robot")
