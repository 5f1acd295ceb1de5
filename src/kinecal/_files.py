"""File helpers used by every layer: atomic writes and strict reads.

Writes go to a temporary file in the target directory, then a rename: an existing output
is never half overwritten. Reads turn every failure into `kinecal.InputError` naming the
file. (This module sits beside `kinecal.errors`, below all layers.)
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from kinecal.errors import InputError

__all__ = [
    "atomic_open",
    "read_json",
    "read_text",
    "read_yaml_mapping",
    "write_bytes_atomic",
    "write_text_atomic",
]


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a temporary file next to `path`; rename it over `path` only on success.

    An exception inside the ``with`` block removes the temporary file and leaves any
    existing `path` untouched.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError("is a directory; expected a file path to write", file=path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:  # parent is a file, no permission, read-only file system
        raise InputError(f"cannot write here ({exc.strerror or exc})", file=path) from None
    binary = "b" in mode
    try:
        os.chmod(tmp, _file_mode(path))  # mkstemp makes 0600; a result file is 0644-like
        with os.fdopen(fd, mode, encoding=None if binary else encoding, newline=None) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _file_mode(path: Path) -> int:
    """Mode of the existing `path`, else what ``open()`` would give under the umask."""
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write `text` to `path` atomically (UTF-8)."""
    with atomic_open(path, "w") as fh:
        fh.write(text)


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write `data` to `path` atomically."""
    with atomic_open(path, "wb", encoding=None) as fh:
        fh.write(data)


def read_text(path: str | Path) -> str:
    """The UTF-8 text of `path`; `InputError` (with the file) when missing or unreadable."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a file", file=path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"not a readable text file ({exc})", file=path) from None


def read_json(path: str | Path) -> Any:
    """The JSON document in `path`; `InputError` naming the file (and line) otherwise."""
    text = read_text(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON at line {exc.lineno}: {exc.msg}", file=path) from None


def read_yaml_mapping(path: str | Path, text: str | None = None) -> dict:
    """The YAML mapping in `path` (or in `text` read from it); `InputError` otherwise."""
    import yaml

    text = read_text(path) if text is None else text
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise InputError(f"not valid YAML{where}", file=path) from None
    if not isinstance(data, dict):
        raise InputError("expected a YAML mapping (key: value) at the top level", file=path)
    return data
