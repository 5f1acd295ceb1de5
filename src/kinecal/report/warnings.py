"""The warnings box at the top of every report (plausibility diagnostics, docs/diagnostics.md)."""

from __future__ import annotations

import html
from collections.abc import Iterable
from typing import Any

__all__ = ["warnings_section"]

_STYLE = ("background:#fff4e5;border-left:4px solid #e69500;padding:.4em 1em;"
          "margin:1em 0")


def _pair(w: Any) -> tuple[str, str]:
    if isinstance(w, dict):
        return str(w.get("code", "")), str(w.get("message", ""))
    return str(getattr(w, "code", "")), str(getattr(w, "message", w))


def warnings_section(warnings: Iterable[Any] | None) -> str:
    """A highlighted ``<section id="warnings">`` listing each warning's message and code
    (`kinecal.diagnostics.Diagnostic` objects or ``{code, message}`` dicts, escaped); the
    empty string when there are none."""
    items = [_pair(w) for w in warnings or []]
    if not items:
        return ""
    rows = "".join(f"<li>{html.escape(msg)} <code>[{html.escape(code)}]</code></li>"
                   for code, msg in items)
    return (f'<section id="warnings" style="{_STYLE}"><h2>Warnings ({len(items)})</h2>'
            "<p>kinecal found something implausible; check before trusting the numbers below "
            "(docs/diagnostics.md explains each code).</p>"
            f"<ul>{rows}</ul></section>")
