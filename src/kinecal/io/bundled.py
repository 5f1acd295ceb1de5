"""Bundled machine files (``kinecal/robots/*.yaml``): listing them and resolving names.

Serial-arm models, robot systems and Stewart geometries share the folder; a file is a
serial model when it has a top-level ``convention`` key, a Stewart geometry when it says
``kind: stewart`` and a system when it says ``kind: system``.

The index of the folder (name -> kind) reads only those top-level keys of each file, as
text, once per process: listing the bundled machines or resolving a name parses no YAML
(the file finally loaded is parsed by its reader, which checks it in full).
"""

from __future__ import annotations

import functools
import re
from importlib import resources
from pathlib import Path

from kinecal.errors import InputError

__all__ = ["bundled_index", "bundled_names", "input_file", "machine_kind",
           "resolve_machine_file", "robots_dir"]

#: kind -> what to call it in messages
KINDS = {"model": "model", "geometry": "geometry", "system": "system"}
#: kind -> the machine it describes, in messages that tell one kind from the other
_WHAT = {"model": "serial-arm model", "geometry": "Stewart-platform geometry",
         "system": "robot system"}

_CONVENTION = re.compile(r"^convention[ \t]*:[ \t]*(?!null\b|~|#|$)\S", re.MULTILINE)
_STEWART = re.compile(r"""^kind[ \t]*:[ \t]*["']?stewart["']?[ \t]*(#.*)?$""", re.MULTILINE)
_SYSTEM = re.compile(r"""^kind[ \t]*:[ \t]*["']?system["']?[ \t]*(#.*)?$""", re.MULTILINE)


def robots_dir() -> Path:
    """Folder of the bundled machine files."""
    return Path(str(resources.files("kinecal") / "robots"))


def _kind(text: str) -> str | None:
    """``model``, ``geometry``, ``system`` or None, from a machine file's top-level keys."""
    if _STEWART.search(text):
        return "geometry"
    if _SYSTEM.search(text):
        return "system"
    if _CONVENTION.search(text):
        return "model"
    return None


@functools.lru_cache(maxsize=1)
def bundled_index() -> dict[str, str]:
    """Name -> kind (``model`` or ``geometry``) of every bundled machine file, sorted."""
    out = {}
    for p in sorted(robots_dir().glob("*.yaml")):
        try:
            kind = _kind(p.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError):
            continue
        if kind is not None:
            out[p.stem] = kind
    return out


def machine_kind(path: str | Path) -> str | None:
    """``model``, ``geometry`` or None (not a machine file, or unreadable: its reader says
    why) of the file at `path`, from its top-level keys (the first megabyte)."""
    try:
        with open(path, "rb") as fh:
            return _kind(fh.read(1 << 20).decode("utf-8", "replace"))
    except OSError:
        return None


def bundled_names(kind: str) -> list[str]:
    """Sorted names of the bundled files of `kind` (``model``, ``geometry``, ``system``)."""
    if kind not in KINDS:
        raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    return [name for name, k in bundled_index().items() if k == kind]


def resolve_machine_file(name_or_path: str | Path, kind: str, option: str | None = None) -> Path:
    """Path of a `kind` file given a bundled name or a path; `InputError` if neither."""
    label = KINDS[kind]
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if path.is_dir():
            raise InputError(f"is a directory, expected a {label} file (YAML)", file=path)
        if not path.is_file():
            raise InputError("file not found", file=path)
        return path
    found = bundled_index().get(str(name_or_path))
    if found == kind:
        return robots_dir() / f"{name_or_path}.yaml"
    if found is not None:  # the other kind: say which, not "unknown"
        raise InputError(
            f"{str(name_or_path)!r} is a bundled {_WHAT[found]}, not a {_WHAT[kind]} "
            f"(bundled {_WHAT[kind]}s: {', '.join(bundled_names(kind))})", option=option)
    raise InputError(
        f"unknown {label} {str(name_or_path)!r}: not a file and not a bundled {label} "
        f"(bundled: {', '.join(bundled_names(kind))})",
        option=option,
    )


def input_file(spec: str | Path) -> Path | None:
    """The file an input argument reads, without reading it: an existing path, a bundled
    machine file (model or Stewart geometry name), or a bundled measurement set
    (``NAME:PART``); None when it is none of these (the reader reports that mistake)."""
    path = Path(spec)
    if path.exists():
        return path
    text = str(spec)
    if "/" not in text and "\\" not in text and (robots_dir() / f"{text}.yaml").is_file():
        return robots_dir() / f"{text}.yaml"
    from kinecal.datasets import DATASETS, bundled_csv

    if text in DATASETS and "pairs" in DATASETS[text]["parts"]:  # a hand-eye recording
        return bundled_csv(f"{text}:pairs")
    if ":" in text and not path.suffix:
        try:
            return bundled_csv(text)
        except InputError:
            return None
    return None
