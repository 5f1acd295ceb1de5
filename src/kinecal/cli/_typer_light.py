"""Plain command-line values converted without pydantic, for a fast start of every command.

typer 0.2x converts each parameter's value through a pydantic ``TypeAdapter``: importing
pydantic and building the adapters costs 0.05-0.1 s of CPU per command, more than the
whole work of ``kinecal fk`` of one pose. `install` makes typer convert the values that
are plain beyond doubt itself (a ``str``; a non-empty path; a decimal integer or float
literal; lists of these) to exactly what the adapter returns, and hand every other value
and every other parameter type (choices, clamped or ranged numbers out of range, custom
parsers, files, dates...) to typer's own adapter, which then also words the error. So
values, errors and messages are typer's. tests/cli/test_typer_light.py checks the
conversions against typer's adapters on many values. With a typer that has no such
adapters (older releases, or a layout this module does not know), nothing is changed.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

__all__ = ["install", "plain_value"]

#: no conversion: hand the value to typer's adapter
DEFER = object()

_INT = re.compile(r"-?(?:0|[1-9][0-9]{0,17})")
_FLOAT = re.compile(r"-?(?:[0-9]{1,30}(?:\.[0-9]{0,30})?|\.[0-9]{1,30})(?:[eE][-+]?[0-9]{1,3})?")


def _plain_leaf(annotation: Any, info: Any, value: Any, path: Any) -> Any:
    """`value` converted to the leaf type `annotation`, or `DEFER`. `path(value)` is the
    path conversion (typer's checks of an existing path included)."""
    if annotation is bool:  # a flag's value (a typed-in "yes" goes to the adapter)
        return value if isinstance(value, bool) else DEFER
    if annotation is str:
        return value if type(value) is str else DEFER
    if annotation is Path:
        if type(value) is str:
            return path(value) if value and "\0" not in value else DEFER
        return path(value) if isinstance(value, Path) else DEFER
    if getattr(info, "clamp", False) or annotation not in (int, float):
        return DEFER
    if type(value) is str:  # typed in
        if not (_INT if annotation is int else _FLOAT).fullmatch(value):
            return DEFER
        out: Any = annotation(value)
    elif type(value) is int and abs(value) < 2**53:  # a default
        out = annotation(value)
    elif type(value) is float and annotation is float:
        out = value
    else:
        return DEFER
    if out - out != 0:  # inf or nan: the adapter decides
        return DEFER
    lo, hi = getattr(info, "min", None), getattr(info, "max", None)
    if (lo is not None and out < lo) or (hi is not None and out > hi):
        return DEFER
    return out


def plain_value(annotation: Any, info: Any, value: Any, path: Any) -> Any:
    """The value typer's adapter would return for `value` of a parameter annotated
    `annotation` (``str``, ``Path``, ``int``, ``float``, ``bool``, or a list of one of these) with
    the typer parameter information `info`, or `DEFER` when not beyond doubt."""
    if getattr(annotation, "__origin__", None) is list:
        (leaf,) = annotation.__args__
        if not isinstance(value, list | tuple):
            return DEFER
        out = [_plain_leaf(leaf, info, v, path) for v in value]
        return DEFER if any(v is DEFER for v in out) else out
    return _plain_leaf(annotation, info, value, path)


_LEAVES = (str, Path, int, float, bool)


def _handled(annotation: Any, info: Any) -> bool:
    if getattr(info, "parser", None) is not None:
        return False
    if getattr(annotation, "__origin__", None) is list:
        args = getattr(annotation, "__args__", ())
        return len(args) == 1 and args[0] in _LEAVES
    return annotation in _LEAVES


def install() -> bool:
    """Make typer convert plain values itself (module docstring); False when this typer
    has no pydantic adapters to spare."""
    try:
        from dataclasses import dataclass

        from typer import _coercion, core
        from typer._param_types import coerce_cli_path

        base = _coercion.RuntimeParam
        original = core.build_runtime_param
    except (ImportError, AttributeError):
        return False
    if getattr(original, "kinecal_light", False):
        return True

    @dataclass(frozen=True)
    class PlainRuntimeParam(base):  # type: ignore[misc, valid-type]
        """A str, path or number converted here; anything else by typer's adapter."""

        descriptor: Any

        def _coerce_value(self, value: Any, param: Any, ctx: Any) -> Any:
            info = self.parameter_info
            path_type = info.path_type or Path

            def path(text: str) -> Any:
                return coerce_cli_path(path_type(text), info, path_type=path_type,
                                       param=param, ctx=ctx)

            out = (plain_value(self.annotation, info, value, path)
                   if path_type is Path else DEFER)
            if out is DEFER:
                return original(self.descriptor)._coerce_value(value, param, ctx)
            return out

    def build_runtime_param(descriptor: Any) -> Any:
        if descriptor.file_annotation is None and _handled(descriptor.annotation,
                                                           descriptor.parameter_info):
            return PlainRuntimeParam(parameter_info=descriptor.parameter_info,
                                     annotation=descriptor.annotation, descriptor=descriptor)
        return original(descriptor)

    build_runtime_param.kinecal_light = True  # type: ignore[attr-defined]
    core.build_runtime_param = build_runtime_param
    return True
