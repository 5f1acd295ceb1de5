"""Option values converted without pydantic (`kinecal.cli._coercion`) equal typer's own
conversion: the same value and type, or, where the plain path declines, typer's adapter
with its refusal and message."""

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
import typer._coercion as typer_coercion
from typer._click.exceptions import BadParameter
from typer.models import ArgumentInfo, OptionInfo

import kinecal.cli._app  # noqa: F401  (the typer app installs the plain converter)
from kinecal.cli._coercion import _UNSET, plain_value

INTS = ["0", "3", "-3", "+3", "007", "-0", "123456789012345678", "1234567890123456789",
        " 3", "3 ", "3.0", "1_000", "0x10", "1e3", "", "abc", "\u0663", "--1",
        "99999999999999999999999"]
FLOATS = ["1.5", "-1.5e-3", "+2", ".5", "5.", "00.5", "1E5", "1e-320", "1e400", "-0",
          "-0.0", "0.1", "2.2250738585072014e-308", "123456789.123456789e-5", "1e+08",
          " 1.5", "1.5 ", "1_0.5", "inf", "-inf", "nan", "Infinity", "1e", "e5", ".", "",
          "1.2.3", "0x1p3", "1e99999", "\u0661.5"]
STRS = ["", "abc", " spaced ", "chessboard:9x6:25", "\u00e9t\u00e9", "-", "a\x00b"]


def _typer(annotation, info=None):
    desc = typer_coercion.resolve_type_descriptor(annotation, info or OptionInfo())
    return typer_coercion.build_runtime_param(desc)  # typer's own (pydantic) converter


def _same(a, b):
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return type(a) is type(b) and a == b and (not isinstance(a, float)
                                              or math.copysign(1, a) == math.copysign(1, b))


@pytest.mark.parametrize(("annotation", "values"), [(int, INTS), (float, FLOATS),
                                                    (str, STRS), (bool, [True, False])])
def test_plain_values_equal_typers_conversion(annotation, values):
    ref = _typer(annotation)
    taken = 0
    for v in values:
        ours = plain_value(annotation, v)
        try:
            theirs = ref._coerce_value(v, param=None, ctx=None)
        except BadParameter:
            assert ours is _UNSET, (annotation, v)  # refusals stay typer's
            continue
        if ours is not _UNSET:
            taken += 1
            assert _same(ours, theirs), (annotation, v, ours, theirs)
    assert taken >= len(values) // 3  # the plain path does take the common literals


def test_random_decimal_literals_round_as_pydantic():
    """Long mantissas and extreme exponents: Python's float() and pydantic's parser both
    round correctly, so the plain path gives the same double on every literal."""
    import numpy as np

    rng = np.random.default_rng(11)
    ref = _typer(float)
    for _ in range(3000):
        digits = "".join(rng.choice(list("0123456789"), int(rng.integers(1, 30))))
        cut = int(rng.integers(0, len(digits) + 1))
        text = f"{rng.choice(['', '-', '+'])}{digits[:cut]}.{digits[cut:]}"
        if rng.random() < 0.6:
            text += f"e{int(rng.integers(-330, 330))}"
        ours = plain_value(float, text)
        assert ours is not _UNSET, text
        assert _same(ours, ref._coerce_value(text, param=None, ctx=None)), text


def test_installed_converter_on_every_kind(tmp_path):
    """Through typer's parameter machinery (the patched builder): plain values, the values
    it declines and their refusals, paths with typer's existence checks."""
    from typer import core

    assert core.build_runtime_param is not typer_coercion.build_runtime_param
    for annotation, values in ((int, INTS), (float, FLOATS), (str, STRS)):
        ours = core.build_runtime_param(
            typer_coercion.resolve_type_descriptor(annotation, OptionInfo()))
        ref = _typer(annotation)
        for v in values:
            try:
                want = ref._coerce_value(v, param=None, ctx=None)
            except BadParameter as exc:
                with pytest.raises(BadParameter) as got:
                    ours._coerce_value(v, param=None, ctx=None)
                assert got.value.message == exc.message
                continue
            assert _same(ours._coerce_value(v, param=None, ctx=None), want), (annotation, v)
    for annotation, values in ((list[str], STRS), (list[float], FLOATS), (list[int], INTS)):
        desc = typer_coercion.resolve_type_descriptor(annotation, OptionInfo())
        ours, ref = core.build_runtime_param(desc), typer_coercion.build_runtime_param(desc)
        for value in ((), tuple(values[:3]), tuple(values)):  # a repeated option's values
            try:
                want = ref._coerce_value(value, param=None, ctx=None)
            except BadParameter as exc:
                with pytest.raises(BadParameter) as got:
                    ours._coerce_value(value, param=None, ctx=None)
                assert got.value.message == exc.message
                continue
            got = ours._coerce_value(value, param=None, ctx=None)
            assert type(got) is type(want) and len(got) == len(want)
            assert all(_same(a, b) for a, b in zip(got, want, strict=True)), (annotation, value)
    f = tmp_path / "f.csv"
    f.write_text("x\n")
    for info in (OptionInfo(), ArgumentInfo(), OptionInfo(exists=True),
                 OptionInfo(exists=True, dir_okay=False), OptionInfo(resolve_path=True)):
        desc = typer_coercion.resolve_type_descriptor(Path, info)
        ours, ref = core.build_runtime_param(desc), typer_coercion.build_runtime_param(desc)
        for v in (str(f), str(tmp_path), str(tmp_path / "missing.csv"), "rel/x.csv", "-", ""):
            try:
                want = ref._coerce_value(v, param=None, ctx=None)
            except BadParameter as exc:
                with pytest.raises(BadParameter) as got:
                    ours._coerce_value(v, param=None, ctx=None)
                assert got.value.message == exc.message
                continue
            assert _same(ours._coerce_value(v, param=None, ctx=None), want), (info, v)


def test_command_runs_without_pydantic(tmp_path):
    """A command whose options are plain values imports no pydantic (typer converts every
    option before the command runs; this one then stops at its empty image folder); a bad
    number still gets typer's message and exit 2."""
    q = tmp_path / "q.csv"
    q.write_text("image,flange_x\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    argv = ["handeye-images", str(tmp_path / "empty"), str(q), "--board", "chessboard:9x6:25",
            "--setup", "eye-to-hand", "--robot-noise", "auto", "--out", str(tmp_path / "x.json")]
    (tmp_path / "empty").mkdir()
    code = ("import io, contextlib, sys\nfrom kinecal.cli import main\n"
            "with contextlib.redirect_stderr(io.StringIO()) as err:\n"
            f"    assert main({argv!r}) == 2\n"
            "assert 'no images in the folder' in err.getvalue(), err.getvalue()\n"
            "assert not [m for m in sys.modules if m.startswith('pydantic')]")
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
    out = subprocess.run([sys.executable, "-m", "kinecal", *argv, "--min-corners", "1.5"],
                         capture_output=True, text=True, env=env)
    assert out.returncode == 2
    assert "Invalid value for '--min-corners'" in out.stderr and "integer" in out.stderr


@pytest.mark.parametrize("annotation", [int, float])
def test_typed_defaults_and_ranges_equal_typers(annotation):
    """A command's default arrives typed (``--seed`` 0 with ``min=0``); a number outside
    an option's range goes to typer's adapter and its refusal."""
    from typer import core

    values = [0, -0, 1, -7, 2**53 - 1, 2**53, 2**80, 0.0, -0.0, 1.5, 1e-300, 5e-324,
              1.7976931348623157e308, float("inf"), float("nan"), True, False, "-1", "3",
              "11", "0.5", "-0.0"]
    infos = [OptionInfo(), OptionInfo(min=0), OptionInfo(max=10), OptionInfo(min=-5, max=5),
             OptionInfo(min=1, clamp=True)]
    taken = 0
    for info in infos:
        desc = typer_coercion.resolve_type_descriptor(annotation, info)
        ours, ref = core.build_runtime_param(desc), typer_coercion.build_runtime_param(desc)
        for v in values:
            if annotation is int and isinstance(v, float):
                continue
            try:
                want = ref._coerce_value(v, param=None, ctx=None)
            except BadParameter as exc:
                with pytest.raises(BadParameter) as got:
                    ours._coerce_value(v, param=None, ctx=None)
                assert got.value.message == exc.message, (annotation, info.min, v)
                continue
            assert _same(ours._coerce_value(v, param=None, ctx=None), want), (info.min, v)
            taken += plain_value(annotation, v) is not _UNSET
    assert taken > 20
