"""kinecal.diagnostics: collection, strict mode, Python warnings."""

import warnings

import pytest

from kinecal.diagnostics import Diagnostic, KinecalWarning, collect, format_warning, strict, warn
from kinecal.errors import InputError


def test_nested_collectors_receive_each_diagnostic_once():
    with collect() as outer:
        warn("a-code", "first")
        with collect() as inner:
            warn("b-code", "second  message\nwrapped")
            warn("b-code", "second message wrapped")
    assert outer == [Diagnostic("a-code", "first"), Diagnostic("b-code", "second message wrapped")]
    assert inner == [Diagnostic("b-code", "second message wrapped")]
    assert inner[0].to_dict() == {"code": "b-code", "message": "second message wrapped"}
    assert format_warning(inner[0]) == "kinecal: warning: second message wrapped [b-code]"


def test_python_warnings_only_when_the_outermost_collector_asks():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with collect():  # the command line: prints them itself
            with collect(python_warnings=True):
                warn("x", "quiet")
        assert not caught
        with collect(python_warnings=True):  # the Python API
            warn("y", "loud")
        warn("z", "no collector")
    assert [str(w.message) for w in caught] == ["loud [y]", "no collector [z]"]
    assert all(issubclass(w.category, KinecalWarning) for w in caught)


def test_strict_raises_input_error():
    with collect() as found, strict(), pytest.raises(InputError, match=r"too few \[few\]"):
        warn("few", "too few")
    assert found == []


def test_cli_warnings_scope_prints_and_merges(capsys):
    from kinecal.cli._common import warnings_scope, with_warnings

    with pytest.raises(RuntimeError), warnings_scope() as found:
        warn("late-code", "printed even when the command fails")
        raise RuntimeError("boom")
    err = capsys.readouterr().err
    assert err == "kinecal: warning: printed even when the command fails [late-code]\n"
    merged = with_warnings({"warnings": [{"code": "a", "message": "m"}]},
                           [Diagnostic("a", "m"), *found])
    assert merged["warnings"] == [{"code": "a", "message": "m"},
                                  {"code": "late-code",
                                   "message": "printed even when the command fails"}]
    with pytest.raises(InputError), warnings_scope(strict=True):
        warn("x", "y")


def test_every_code_raised_in_the_sources_is_listed_and_documented():
    """Each ``warn("code", ...)`` anywhere in src/ has an entry in the code registry
    (kinecal.calibration.diagnostics.CODES) and a section in docs/diagnostics.md."""
    import re
    from pathlib import Path

    from kinecal.calibration.diagnostics import CODES

    root = Path(__file__).resolve().parents[1]
    doc = (root / "docs" / "diagnostics.md").read_text(encoding="utf-8")
    call = re.compile(r"(?<!warnings\.)\bwarn\(\s*(f?)[\"']([^\"']*)[\"']")
    raised: dict[str, str] = {}
    for path in sorted((root / "src" / "kinecal").rglob("*.py")):
        for m in call.finditer(path.read_text(encoding="utf-8")):
            assert not m.group(1), f"{path.name}: a code must be a plain string: {m.group(0)}"
            raised.setdefault(m.group(2), path.name)
    assert len(raised) >= 30 and "joint-errors-not-exported" in raised, sorted(raised)
    for code, where in raised.items():
        assert re.fullmatch(r"[a-z0-9]+(-[a-z0-9]+)*", code), (code, where)
        assert code in CODES, f"{code} ({where}) is missing from CODES"
        assert f"### `{code}`" in doc or f"`{code}`" in doc, f"{code} ({where}) not documented"
