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
