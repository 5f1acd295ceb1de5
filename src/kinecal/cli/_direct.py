"""Commands run without typer when their arguments are plain.

Importing typer and building a command costs 0.02-0.03 s of CPU, a sixth of a one-pose
``kinecal fk`` (a script asking per target pays it on every call) and a tenth of the
start-up of ``kinecal stewart fk``. For the commands in `DIRECT`, `parse` reads an
argument list when every token is plainly one of the command's own: its positional
arguments, none starting with ``-``; its long options as ``--name VALUE`` or
``--name=VALUE`` (a value neither empty nor starting with ``-``), each at most once unless
it may repeat; its flags. The command's body is then called with
exactly the values typer would pass. Anything else (``--help``, a short or unknown option,
``--``, a missing or extra argument, an option whose value typer checks against the disk)
returns None and typer runs the command as before, with its own messages. The table is
checked against the typer commands by tests/cli/test_cli_direct.py (every parameter, its
names, default and kind; and the values of many argument lists).
"""

from __future__ import annotations

import importlib
import sys
from dataclasses import dataclass, field
from typing import Any

__all__ = ["DIRECT", "Direct", "parse", "run"]


@dataclass(frozen=True)
class Direct:
    """A command run directly: its body ``module.function`` and its parameters."""

    module: str
    function: str
    #: positional arguments in order (all required, one value each)
    arguments: tuple[str, ...]
    #: long option -> parameter taking a string value (None when not given)
    options: dict[str, str] = field(default_factory=dict)
    #: long option -> parameter taking repeated string values (a list; () when not given)
    repeated: dict[str, str] = field(default_factory=dict)
    #: flag -> parameter (False when not given)
    flags: dict[str, str] = field(default_factory=dict)
    #: defaults other than these; a parameter in no table above is typer's alone (given on
    #: the command line, typer runs the command; absent, this default)
    defaults: dict[str, Any] = field(default_factory=dict)


#: the commands run directly (by the words that name them)
DIRECT: dict[tuple[str, ...], Direct] = {
    ("fk",): Direct(
        "kinecal.cli._fk_run", "run_fk", ("model", "joints"),
        options={"--base-link": "base_link", "--tip": "tip", "--angle-unit": "angle_unit"},
        repeated={"--tip-link": "tip_link"},
        flags={"--pose": "pose", "--strict": "strict", "--quiet": "quiet"},
        defaults={"params": None},  # a path typer checks on the disk
    ),
    ("stewart", "fk"): Direct(
        "kinecal.cli._stewart_fk", "run_fk", ("geometry", "legs"),
        options={"--method": "method"},
        flags={"--all": "all_modes", "--json": "json_out", "--strict": "strict"},
        defaults={"method": "newton", "seed": 0},  # --seed: typer checks its range
    ),
}


def _plain(value: str) -> bool:
    return bool(value) and not value.startswith("-")


def parse(args: list[str]) -> tuple[Direct, dict[str, Any]] | None:
    """The command and keyword arguments typer would call for `args`, or None (module
    docstring)."""
    words = next((w for w in DIRECT if tuple(args[:len(w)]) == w), None)
    if words is None:
        return None
    cmd = DIRECT[words]
    kwargs: dict[str, Any] = {name: None for name in cmd.options.values()}
    kwargs.update({name: () for name in cmd.repeated.values()})  # typer's "none given"
    kwargs.update({name: False for name in cmd.flags.values()})
    kwargs.update(cmd.defaults)
    seen: set[str] = set()
    positional: list[str] = []
    rest = list(args[len(words):])
    while rest:
        token = rest.pop(0)
        if not token.startswith("-"):
            positional.append(token)
            continue
        name, eq, value = token.partition("=")
        if name in cmd.flags and not eq and name not in seen:
            kwargs[cmd.flags[name]] = True
        elif name in cmd.options or name in cmd.repeated:
            if not eq:
                if not rest:
                    return None
                value = rest.pop(0)
            if not _plain(value):
                return None
            if name in cmd.repeated:
                kwargs[cmd.repeated[name]] = [*kwargs[cmd.repeated[name]], value]
                continue
            if name in seen:
                return None
            kwargs[cmd.options[name]] = value
        else:
            return None
        seen.add(name)
    if len(positional) != len(cmd.arguments):
        return None
    kwargs.update(zip(cmd.arguments, positional, strict=True))
    return cmd, kwargs


def run(cmd: Direct, kwargs: dict[str, Any]) -> Any:
    """Call the body of `cmd` as typer would (end of input -> typer's ``Abort``)."""
    body = getattr(importlib.import_module(cmd.module), cmd.function)
    try:
        return body(**kwargs)
    except EOFError as exc:  # what typer makes of it
        from typer import Abort

        sys.stderr.write("\n")
        raise Abort() from exc
