"""Bundled machine files (``kinecal/robots/*.yaml``): listing them and resolving names.

Serial-arm models and Stewart geometries share the folder; a file is a serial model when
it has a ``convention`` key and a Stewart geometry when ``kind: stewart``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import yaml

from kinecal.errors import InputError

__all__ = ["bundled_names", "resolve_machine_file", "robots_dir"]

#: kind -> (predicate on the file's mapping, what to call it in messages)
KINDS = {
    "model": (lambda d: d.get("convention") is not None, "model"),
    "geometry": (lambda d: d.get("kind") == "stewart", "geometry"),
}


def robots_dir() -> Path:
    """Folder of the bundled machine files."""
    return Path(str(resources.files("kinecal") / "robots"))


def bundled_names(kind: str) -> list[str]:
    """Sorted names of the bundled files of `kind` (``model`` or ``geometry``)."""
    accept, _ = KINDS[kind]
    out = []
    for p in sorted(robots_dir().glob("*.yaml")):
        try:
            data = yaml.safe_load(p.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError):
            continue
        if isinstance(data, dict) and accept(data):
            out.append(p.stem)
    return out


def resolve_machine_file(name_or_path: str | Path, kind: str, option: str | None = None) -> Path:
    """Path of a `kind` file given a bundled name or a path; `InputError` if neither."""
    label = KINDS[kind][1]
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.is_file():
            raise InputError(f"{label} file not found", file=path)
        return path
    names = bundled_names(kind)
    if str(name_or_path) in names:
        return robots_dir() / f"{name_or_path}.yaml"
    raise InputError(
        f"unknown {label} {str(name_or_path)!r}: not a file and not a bundled {label} "
        f"(bundled: {', '.join(names)})",
        option=option,
    )
