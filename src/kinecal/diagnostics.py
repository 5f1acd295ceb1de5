"""Plausibility diagnostics: warnings with stable codes, collected where they arise.

kinecal must never answer implausible input with a confident number and no word of doubt.
A check that finds something suspicious calls `warn` with a stable *code* (for scripts and
tests, e.g. ``scale-mismatch``) and a one-line *message* that says what is probably wrong
and what to do. What happens then depends on the context:

* inside `collect` blocks the diagnostic is appended to every active collector (a
  calibration keeps its own in ``result.warnings``; the command line collects everything a
  command raised, prints ``kinecal: warning: ...`` lines on stderr and writes them into the
  result JSON as ``warnings: [{code, message}]``);
* under `strict` (the command line's ``--strict``) it raises `InputError` at once, before
  any output is written, so the command exits with status 2;
* when the outermost active collector asks for it (the Python API), or when no collector
  is active, it is also issued as a `KinecalWarning` through Python's `warnings` module.

This module sits below every layer (readers, kinematics, calibrations all call `warn`);
the checks themselves live beside the data they judge (``kinecal.calibration.diagnostics``
and the readers).
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from contextvars import ContextVar
from dataclasses import dataclass

from kinecal.errors import InputError

__all__ = [
    "Diagnostic",
    "KinecalWarning",
    "collect",
    "expect",
    "format_warning",
    "is_strict",
    "strict",
    "warn",
]


class KinecalWarning(UserWarning):
    """A plausibility warning of kinecal, issued through Python's `warnings` module."""


@dataclass(frozen=True)
class Diagnostic:
    """One plausibility finding.

    Attributes
    ----------
    code : str
        Stable identifier (lower-case words joined by ``-``), e.g. ``scale-mismatch``.
    message : str
        One line: what is probably wrong and what to do about it.
    """

    code: str
    message: str

    def to_dict(self) -> dict[str, str]:
        """``{"code": ..., "message": ...}`` (the JSON contract)."""
        return {"code": self.code, "message": self.message}


class _Collector(list):
    """A list of `Diagnostic` that also remembers whether to re-issue Python warnings."""

    def __init__(self, python_warnings: bool) -> None:
        super().__init__()
        self.python_warnings = python_warnings


_COLLECTORS: ContextVar[tuple[_Collector, ...]] = ContextVar("kinecal_collectors", default=())
_STRICT: ContextVar[bool] = ContextVar("kinecal_strict", default=False)
_EXPECTED: ContextVar[tuple[tuple[frozenset, list], ...]] = ContextVar("kinecal_expected",
                                                                      default=())


def format_warning(diagnostic: Diagnostic) -> str:
    """The stderr line of a diagnostic: ``kinecal: warning: MESSAGE [CODE]``."""
    text = " ".join(diagnostic.message.split())
    return f"kinecal: warning: {text} [{diagnostic.code}]"


def warn(code: str, message: str) -> Diagnostic:
    """Report an implausibility (see the module docstring for where it goes).

    Parameters
    ----------
    code : str
        Stable code of the check.
    message : str
        One line: what is probably wrong and what to do.

    Returns
    -------
    Diagnostic

    Raises
    ------
    InputError
        Under `strict`: the warning becomes an error (exit status 2 on the command line).
    """
    d = Diagnostic(code, " ".join(str(message).split()))
    for codes, seen in reversed(_EXPECTED.get()):
        if code in codes:
            if d not in seen:
                seen.append(d)
            return d
    if _STRICT.get():
        raise InputError(f"{d.message} [{d.code}] (--strict turns warnings into errors)")
    collectors = _COLLECTORS.get()
    for c in collectors:
        if d not in c:
            c.append(d)
    if not collectors or collectors[0].python_warnings:
        warnings.warn(f"{d.message} [{d.code}]", KinecalWarning, stacklevel=2)
    return d


@contextlib.contextmanager
def collect(python_warnings: bool = False) -> Iterator[list[Diagnostic]]:
    """Collect the diagnostics raised inside the block (nested blocks all receive them).

    Parameters
    ----------
    python_warnings : bool
        When this is the outermost active collector, also issue each diagnostic as a
        `KinecalWarning` (what the Python API does; the command line prints them itself).

    Yields
    ------
    list of Diagnostic
        Filled while the block runs, in order of appearance, without repeats.
    """
    c = _Collector(python_warnings)
    token = _COLLECTORS.set((*_COLLECTORS.get(), c))
    try:
        yield c
    finally:
        _COLLECTORS.reset(token)


@contextlib.contextmanager
def expect(*codes: str) -> Iterator[list[Diagnostic]]:
    """Inside the block, diagnostics with these `codes` are known to the caller.

    They are recorded in the yielded list only: not collected, not printed, not issued as
    Python warnings and not turned into errors by `strict`. For code that sets up a
    condition on purpose (a paper reproduction run with the paper's few poses), never for
    hiding a finding from a user.

    Yields
    ------
    list of Diagnostic
        The expected diagnostics raised inside the block.
    """
    seen: list[Diagnostic] = []
    token = _EXPECTED.set((*_EXPECTED.get(), (frozenset(codes), seen)))
    try:
        yield seen
    finally:
        _EXPECTED.reset(token)


@contextlib.contextmanager
def strict(enabled: bool = True) -> Iterator[None]:
    """Inside the block, `warn` raises `InputError` instead of collecting (``--strict``)."""
    token = _STRICT.set(bool(enabled))
    try:
        yield
    finally:
        _STRICT.reset(token)


def is_strict() -> bool:
    """True inside a `strict` block."""
    return _STRICT.get()
