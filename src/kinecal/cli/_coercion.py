"""Plain option values converted without pydantic.

typer >= 0.2x converts every command-line value through a pydantic ``TypeAdapter``, built
when the command runs: importing pydantic and building the adapters of one command's
options cost 0.06-0.1 s of CPU, more than the work of a one-pose ``kinecal fk`` and most
of what ``kinecal handeye-images`` adds to a plain OpenCV script. kinecal's options are
almost all plain ``str``, ``Path``, ``int``, ``float`` or ``bool`` values (or a ``list``
of them, for a repeated option) parsed further by kinecal itself, so `install` gives typer
a converter that turns those into the very value pydantic would (a string as it is, a
decimal literal by Python's ``int`` / ``float``, a path through typer's own path checks)
and hands anything else to typer's adapter, built then: every refusal and its message
stay typer's (tests/cli/test_cli_coercion.py compares both converters on a corpus of
values).

A typer without this machinery (older releases convert through click) is left alone.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, get_args, get_origin

__all__ = ["install", "plain_value"]

#: decimal literals whose value Python's int() / float() give exactly as pydantic does
#: (pydantic also takes underscores, spaces, "3.0" as an int, inf and nan: those go to it)
_INT = re.compile(r"[+-]?[0-9]{1,18}")
_FLOAT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]{1,4})?")

_UNSET = object()


def plain_value(annotation: Any, value: Any) -> Any:
    """`value` converted to `annotation` when it is a plain case, else `_UNSET`.

    Plain cases: a ``str`` for a ``str`` option; a bool for a ``bool`` one; a decimal
    literal (``[+-]digits`` up to 18 digits, or ``[+-]digits.digits[e[+-]digits]``) for
    an ``int`` or ``float`` one, or a typed default (an int, a finite float). Paths are
    converted by `install`'s converter, which runs typer's own checks on them; numbers
    outside an option's ``min`` / ``max`` go to typer's adapter, which refuses them.
    """
    if annotation is str and type(value) is str:
        return value
    if annotation is bool and type(value) is bool:
        return value
    if type(value) is str:
        if annotation is int and _INT.fullmatch(value):
            return int(value)
        if annotation is float and _FLOAT.fullmatch(value):
            return float(value)
    # a command's own default arrives typed (``--seed`` 0, a tolerance 1e-6)
    if type(value) is int and annotation in (int, float) and abs(value) < 2**53:
        return annotation(value)
    if type(value) is float and annotation is float and math.isfinite(value):
        return value
    return _UNSET


def _in_range(value: Any, info: Any) -> bool:
    """Whether a number lies within the option's ``min`` / ``max`` (typer refuses it
    otherwise, in its own words)."""
    lo, hi = info.min, info.max
    return not ((lo is not None and value < lo) or (hi is not None and value > hi))


def _list_item(annotation: Any) -> Any:
    """``X`` of a ``list[X]`` annotation with a plain ``X``, else None."""
    if get_origin(annotation) is list:
        args = get_args(annotation)
        if len(args) == 1 and args[0] in (str, bool, int, float, Path):
            return args[0]
    return None


def install() -> None:
    """Give typer's options the plain converter (once; no-op on a typer without it)."""
    try:
        import typer.core as core
        from typer._coercion import RuntimeParam
        from typer._param_types import coerce_cli_path
    except ImportError:  # pragma: no cover - typer without pydantic coercion
        return
    full = getattr(core, "build_runtime_param", None)
    if full is None or getattr(full, "_kinecal_plain", False):
        return

    @dataclass(frozen=True)
    class PlainRuntimeParam(RuntimeParam):  # type: ignore[misc]
        """A plain value converted here; anything else by typer's adapter, built then."""

        descriptor: Any = None

        def _coerce_value(self, value: Any, param: Any, ctx: Any) -> Any:
            def path(v: Any) -> Any:
                # typer's own path checks (exists, file_okay...) on the Path pydantic gives
                if type(v) is not str or not v:
                    return _UNSET
                return coerce_cli_path(Path(v), self.parameter_info, path_type=Path,
                                       param=param, ctx=ctx)

            if self.annotation is Path and type(value) is str and value:
                return path(value)
            item = _list_item(self.annotation)
            if item is None:
                out = plain_value(self.annotation, value)
                if out is not _UNSET and (self.annotation not in (int, float)
                                          or _in_range(out, self.parameter_info)):
                    return out
            elif isinstance(value, list | tuple):  # a repeated option: typer gives a list
                items = [path(v) if item is Path else plain_value(item, v) for v in value]
                if all(v is not _UNSET for v in items):
                    return items
            return full(self.descriptor)._coerce_value(value, param=param, ctx=ctx)

    def build(descriptor: Any) -> Any:
        info = descriptor.parameter_info
        item = _list_item(descriptor.annotation)
        plain = ((descriptor.annotation in (str, bool, int, float, Path) or item is not None)
                 and descriptor.file_annotation is None and info.parser is None
                 and getattr(info, "click_type", None) is None
                 and (item is None or (info.min is None and info.max is None))
                 and not getattr(info, "clamp", False)
                 and (descriptor.annotation is not Path or info.path_type in (None, Path)))
        if not plain:
            return full(descriptor)
        return PlainRuntimeParam(parameter_info=info, annotation=descriptor.annotation,
                                 descriptor=descriptor)

    build._kinecal_plain = True  # type: ignore[attr-defined]
    core.build_runtime_param = build
