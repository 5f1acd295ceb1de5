"""Provenance of a report: when, with what, from which files, by whom.

`collect` gathers the date and time (ISO 8601 with the UTC offset; ``SOURCE_DATE_EPOCH``,
when set, fixes it for reproducible files: `kinecal._reproducible`), kinecal's, Python's and
numpy's versions, the command line, the SHA-256 and size of every input file (a folder
input: of every file directly in it, or of those with the suffixes the command reads) and
the optional instrument, operator and note. `provenance_section` renders them as the report's record
block; every report of `kinecal.report` takes a `Provenance` (made with no inputs when
none is given, so that a report always carries its date and version).

Under ``SOURCE_DATE_EPOCH`` the record carries that date, and a report's tables no time a
run took (`time_rows`): the same inputs give the same report byte for byte.
"""

from __future__ import annotations

import hashlib
import platform
import shlex
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from kinecal._reproducible import reproducible, shown_text, source_date_epoch
from kinecal.report.markup import table

__all__ = ["InputFile", "Provenance", "collect", "file_sha256", "provenance_section",
           "time_rows"]

#: bytes read at a time while hashing
_CHUNK = 1 << 20


@dataclass(frozen=True)
class InputFile:
    """One input file: the argument or option that named it, its path, SHA-256 (hex) and
    size in bytes."""

    name: str
    path: str
    sha256: str
    size: int


@dataclass(frozen=True)
class Provenance:
    """Who made a report, when, with which kinecal, from which files.

    Attributes
    ----------
    created : str
        Date and time, ISO 8601 with the UTC offset (``2026-11-27T14:03:12+01:00``).
    version : str
        kinecal's version.
    command : str or None
        The command line (shell-quoted), None for a report made through the Python API.
    inputs : tuple of InputFile
        Every input file with its SHA-256.
    instrument, operator, note : str or None
        As given (``--instrument``, ``--operator``, ``--note``).
    environment : str
        Python, numpy and platform versions.
    """

    created: str
    version: str
    command: str | None = None
    inputs: tuple[InputFile, ...] = field(default_factory=tuple)
    instrument: str | None = None
    operator: str | None = None
    note: str | None = None
    environment: str = ""

    def to_dict(self) -> dict:
        """JSON-ready dict of every field (inputs as ``[{name, path, sha256, size}]``)."""
        return {"created": self.created, "kinecal": self.version, "command": self.command,
                "inputs": [vars(f) for f in self.inputs], "instrument": self.instrument,
                "operator": self.operator, "note": self.note, "environment": self.environment}


def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(_CHUNK):
            h.update(block)
    return h.hexdigest()


def time_rows(seconds: float) -> list[tuple[str, float]]:
    """The ``time [s]`` row of a report's table: none under ``SOURCE_DATE_EPOCH``."""
    return [] if reproducible() else [("time [s]", float(seconds))]


def _now() -> str:
    epoch = source_date_epoch()
    if epoch is not None:
        return datetime.fromtimestamp(epoch, UTC).isoformat(timespec="seconds")
    return datetime.now(UTC).astimezone().isoformat(timespec="seconds")


def _files(name: str, path: Path, suffixes: Sequence[str] | None) -> list[InputFile]:
    if path.is_dir():
        wanted = None if suffixes is None else {s.lower() for s in suffixes}
        members = sorted(p for p in path.iterdir() if p.is_file()
                         and (wanted is None or p.suffix.lower() in wanted))
        return [f for p in members for f in _files(name, p, None)]
    if not path.is_file():
        return []
    return [InputFile(shown_text(name), shown_text(str(path)), file_sha256(path),
                      path.stat().st_size)]


def collect(inputs: Mapping[str, str | Path | None] | None = None, *,
            command: Sequence[str] | str | None = None, instrument: str | None = None,
            operator: str | None = None, note: str | None = None,
            suffixes: Mapping[str, Sequence[str]] | None = None) -> Provenance:
    """The provenance of a report made now.

    Parameters
    ----------
    inputs : mapping of str to path, optional
        Argument or option name -> the file (or folder) it read; None entries and names
        that are not files (a bundled model name) are left out.
    command : sequence of str or str, optional
        The command line (a list is shell-quoted).
    instrument, operator, note : str, optional
        Free text for the record.
    suffixes : mapping of str to sequence of str, optional
        For a folder input: the suffixes of the files it contributes (default all files
        directly in it).

    Returns
    -------
    Provenance
    """
    import numpy as np

    from kinecal import __version__

    found: list[InputFile] = []
    for name, spec in (inputs or {}).items():
        if spec is not None:
            found += _files(name, Path(spec), (suffixes or {}).get(name))
    if command is not None and not isinstance(command, str):
        command = shlex.join(str(c) for c in command)
    instrument, operator, note, command = (None if t is None else shown_text(t)
                                           for t in (instrument, operator, note, command))
    env = (f"Python {platform.python_version()}, numpy {np.__version__}, "
           f"{platform.system()} {platform.machine()}")
    return Provenance(_now(), __version__, command, tuple(found), instrument or None,
                      operator or None, note or None, env)


def provenance_section(prov: Provenance | None) -> str:
    """The ``<section id="provenance">`` record block: date, versions, operator,
    instrument, note, command line and the table of input files with their SHA-256."""
    prov = collect() if prov is None else prov
    rows = [("date and time (ISO 8601)", prov.created), ("kinecal", prov.version),
            ("operator", prov.operator or "-"), ("instrument", prov.instrument or "-")]
    if prov.note:
        rows.append(("note", prov.note))
    rows += [("command", prov.command or "Python API (no command line)"),
             ("environment", prov.environment)]
    body = table(None, rows, left=2).replace("<table>", '<table class="record">', 1)
    if prov.inputs:
        body += table(["input", "file", "SHA-256", "bytes"],
                      [(f.name, f.path, f.sha256, f.size) for f in prov.inputs],
                      left=3).replace("<table>", '<table class="files">', 1)
        body += ("<p>Check a file against this record with <code>sha256sum FILE</code> "
                 "(or <code>certutil -hashfile FILE SHA256</code> on Windows).</p>")
    else:
        body += "<p>No input file recorded.</p>"
    return f'<section id="provenance"><h2>Record</h2>{body}</section>'

