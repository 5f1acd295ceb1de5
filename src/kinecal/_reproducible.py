"""Reproducible files: ``SOURCE_DATE_EPOCH`` read and checked once for every layer.

With ``SOURCE_DATE_EPOCH`` set (the reproducible-builds convention: whole seconds since
1970, as ``date +%s`` prints them, negative before 1970) kinecal's files and summaries are
the same byte for byte from run to run: a report's record carries that date
(`kinecal.report.provenance`), and the times a run took are left out of summaries, reports
and result files (`reproducible`, `seconds_text`). A value that is not such an integer, or
a date outside the years 1-9999, is refused (`InputError`). (This module sits beside
`kinecal.errors`, below all layers.)
"""

from __future__ import annotations

import os
import re
from datetime import UTC, datetime

from kinecal.errors import InputError

__all__ = ["reproducible", "seconds_text", "shown_text", "source_date_epoch"]


def source_date_epoch() -> int | None:
    """``SOURCE_DATE_EPOCH`` as whole seconds since 1970 (None when unset or empty).

    Raises
    ------
    InputError
        Not an integer (``abc``, ``1e20``, ``1.5``), or a date outside the years 1-9999.
    """
    text = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if not text:
        return None
    if not re.fullmatch(r"[+-]?[0-9]{1,20}", text):
        raise InputError(f"SOURCE_DATE_EPOCH={shown_text(text)[:40]!r}: expected whole seconds "
                         "since 1970 (an integer, as date +%s prints), or unset it")
    epoch = int(text)
    try:
        datetime.fromtimestamp(epoch, UTC)
    except (OverflowError, OSError, ValueError):
        raise InputError(f"SOURCE_DATE_EPOCH={text}: a date beyond the years 1-9999; expected "
                         "whole seconds since 1970 (as date +%s prints)") from None
    return epoch


def reproducible() -> bool:
    """True when ``SOURCE_DATE_EPOCH`` is set: files then carry no time a run took."""
    return source_date_epoch() is not None


def seconds_text(seconds: float) -> str:
    """``", 0.42 s"``: the time a run took, for a summary line; empty under
    ``SOURCE_DATE_EPOCH``."""
    return "" if reproducible() else f", {seconds:.3g} s"


def shown_text(text: str) -> str:
    """`text` as it can be written in UTF-8: bytes of the command line or of a file name
    that are not UTF-8 (Python keeps them as lone surrogates) shown as ``\\xff``."""
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
