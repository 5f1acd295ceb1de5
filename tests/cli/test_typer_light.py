"""Plain command-line values converted without pydantic (`kinecal.cli._typer_light`) give
what typer's own pydantic adapters give, on many values; anything else goes to typer."""

import math
from pathlib import Path

import numpy as np
import pytest

typer = pytest.importorskip("typer")
_coercion = pytest.importorskip("typer._coercion")

from typer.models import ArgumentInfo, OptionInfo  # noqa: E402

from kinecal.cli._typer_light import DEFER, plain_value  # noqa: E402


def _typer(annotation, info, value):
    """typer's own conversion (its pydantic adapter): ('ok', value) or ('error', text)."""
    from typer._adapters import try_build_adapter
    from typer._click.exceptions import BadParameter

    runtime = _coercion.AdapterRuntimeParam(parameter_info=info, annotation=annotation,
                                            adapter=try_build_adapter(annotation, info))
    try:
        return "ok", runtime._coerce_value(value, param=None, ctx=None)
    except BadParameter as exc:
        return "error", str(exc)


def _same(a, b):
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(map(_same, a, b))
    if isinstance(a, float) and isinstance(b, float):
        return (a == b and math.copysign(1, a) == math.copysign(1, b)) or (
            math.isnan(a) and math.isnan(b))
    return type(a) is type(b) and a == b


def _strings(rng, n=400):
    edge = ["", " ", "0", "-0", "+0", "00", "01", "1", "-1", "+1", "1_000", "1__0", " 5",
            "5 ", "5.", ".5", "-.5", "1.0", "1e3", "1E-3", "1e+3", "1e400", "-1e400", "inf",
            "-inf", "nan", "NaN", "0x10", "0b1", "1.5.2", "--1", "١٢", "1e", "e1", ".",
            "9" * 18, "9" * 19, "9" * 40, "-" + "9" * 18, "1" * 31, "0." + "1" * 31,
            "3.141592653589793238462643383279", "4.9e-324", "2.2250738585072014e-308",
            "1.7976931348623157e308", "1.7976931348623159e308", "\udcff", "a\0b", "~", "x y",
            "true", "yes", "-", "a/b/", "//a", "a//b", "./x", "\t7\n"]
    chars = "0123456789.-+eE_ x"
    rand = ["".join(rng.choice(list(chars), rng.integers(1, 12))) for _ in range(n)]
    floats = [repr(float(v)) for v in rng.standard_normal(100) * 10.0 ** rng.integers(
        -320, 308, 100)]
    return edge + rand + floats + [str(int(v)) for v in rng.integers(-10**17, 10**17, 50)]


INFOS = [OptionInfo(), ArgumentInfo(), OptionInfo(min=0), OptionInfo(max=10),
         OptionInfo(min=-5, max=5), OptionInfo(min=0.5), OptionInfo(min=1, clamp=True)]


@pytest.mark.parametrize("annotation", [str, int, float])
def test_leaf_values_agree_with_typer(annotation):
    rng = np.random.default_rng(3)
    taken = 0
    infos = {str: INFOS[:2], int: [i for i in INFOS if i.min != 0.5], float: INFOS}
    for info in infos[annotation]:
        for s in _strings(rng):
            mine = plain_value(annotation, info, s, path=None)
            if mine is DEFER:
                continue
            taken += 1
            kind, theirs = _typer(annotation, info, s)
            assert kind == "ok" and _same(mine, theirs), (annotation, info.min, info.max, s,
                                                          mine, theirs)
    assert taken > 300


def test_paths_agree_with_typer(tmp_path):
    rng = np.random.default_rng(4)
    (tmp_path / "file.csv").write_text("x\n")
    (tmp_path / "dir").mkdir()
    info = OptionInfo()
    from typer._param_types import coerce_cli_path

    def path(text):
        return coerce_cli_path(Path(text), info, path_type=Path, param=None, ctx=None)

    values = _strings(rng, 100) + [str(tmp_path / "file.csv"), str(tmp_path / "dir"),
                                   str(tmp_path / "missing"), str(tmp_path) + "/"]
    for s in values:
        mine = plain_value(Path, info, s, path)
        if mine is DEFER:
            assert s == "" or "\0" in s
            continue
        kind, theirs = _typer(Path, info, s)
        assert kind == "ok" and mine == theirs and type(mine) is type(theirs), (s, theirs)


def test_lists_and_flags():
    info = OptionInfo()
    assert plain_value(list[str], info, ("a", "b"), None) == ["a", "b"]
    assert _typer(list[str], info, ("a", "b")) == ("ok", ["a", "b"])
    assert plain_value(list[int], info, ("1", "x"), None) is DEFER
    assert plain_value(list[int], info, ("1", "-2"), None) == [1, -2]
    assert _typer(list[int], info, ("1", "-2")) == ("ok", [1, -2])
    assert plain_value(bool, info, True, None) is True
    assert plain_value(bool, info, "yes", None) is DEFER
    assert plain_value(str, info, 5, None) is DEFER


@pytest.mark.parametrize("annotation", [int, float])
def test_typed_defaults_agree_with_typer(annotation):
    """A command's default arrives typed (``--seed`` 0, a tolerance 1e-6)."""
    values = [0, -0, 1, -7, 2**53 - 1, 2**53, 2**80, 0.0, -0.0, 1.5, 1e-300, 5e-324,
              1.7976931348623157e308, float("inf"), float("nan"), True, False, None]
    for info in INFOS[:5]:
        for v in values:
            mine = plain_value(annotation, info, v, None)
            if mine is not DEFER:
                kind, theirs = _typer(annotation, info, v)
                assert kind == "ok" and _same(mine, theirs), (annotation, info.min, v)
    assert plain_value(annotation, OptionInfo(), 3, None) == 3


def test_cli_errors_are_typers(tmp_path, capsys):
    """A value the fast conversion defers on is worded by typer, as before."""
    from kinecal.cli import main

    assert main(["simulate", "ur5", "--poses", "abc", "--out", str(tmp_path / "m.csv")]) == 2
    err = capsys.readouterr().err
    assert "--poses" in err and "valid integer" in err, err
