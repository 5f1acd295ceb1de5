"""Where the registry is (``--db``, ``$KINECAL_DB``, ``kinecal.db``) and the dates it records.

A ``--db`` value is an SQLite file path (created on first write) or a PostgreSQL URL
(``postgresql://user@host/db``, ``postgresql+psycopg://...``; a URL of another database
is refused). Dates are ISO 8601 with their UTC offset, to the second; the time a record
is written is now, or ``SOURCE_DATE_EPOCH`` when set (reproducible records, as reports).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from kinecal.errors import InputError

__all__ = ["DEFAULT_FILE", "ENV", "Location", "format_date", "hide_password", "locate", "now",
           "parse_date"]

#: the registry file in the working folder when neither --db nor $KINECAL_DB says otherwise
DEFAULT_FILE = "kinecal.db"
#: the environment variable naming the registry
ENV = "KINECAL_DB"
#: URL schemes of a PostgreSQL registry
_POSTGRES = ("postgresql://", "postgres://", "postgresql+psycopg://")
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")


@dataclass(frozen=True)
class Location:
    """A registry's address.

    Attributes
    ----------
    backend : str
        ``sqlite`` or ``postgresql``.
    target : str
        The SQLite file path, or the PostgreSQL URL (driver part set to psycopg).
    shown : str
        What messages call it (a URL without its password).
    option : str
        Where it came from: ``--db``, ``$KINECAL_DB`` or the default.
    """

    backend: str
    target: str
    shown: str
    option: str

    @property
    def path(self) -> Path:
        """The SQLite file (SQLite only)."""
        return Path(self.target)


def hide_password(text: str) -> str:
    """`text` with the password of any URL in it replaced by ``***``."""
    return re.sub(r"(://[^:/@\s]+):[^@/\s]*@", r"\1:***@", text)


def locate(db: str | os.PathLike | None = None) -> Location:
    """The registry named by `db`, else by ``$KINECAL_DB``, else ``kinecal.db`` here."""
    if db is not None:
        text, option = os.fspath(db), "--db"
    elif os.environ.get(ENV, "").strip():
        text, option = os.environ[ENV].strip(), f"${ENV}"
    else:
        text, option = DEFAULT_FILE, "--db"
    if not text.strip():
        raise InputError("expected an SQLite file path or a postgresql:// URL, got nothing",
                         option=option)
    if text.startswith(_POSTGRES):
        rest = text.split("://", 1)[1]
        return Location("postgresql", "postgresql+psycopg://" + rest, hide_password(text),
                        option)
    if _URL.match(text) and not text.lower().startswith("sqlite:"):
        scheme = text.split("://", 1)[0]
        raise InputError(f"a {scheme}:// URL: the registry is an SQLite file path or a "
                         "postgresql:// URL", option=option)
    if text.lower().startswith("sqlite:///"):
        text = text[len("sqlite:///"):]
    if text in (":memory:", ""):
        raise InputError("an in-memory database keeps nothing: give a file path",
                         option=option)
    return Location("sqlite", text, text, option)


def now() -> datetime:
    """Now (UTC, to the second), or ``SOURCE_DATE_EPOCH`` when set (`kinecal._reproducible`:
    checked once for every layer)."""
    from kinecal._reproducible import source_date_epoch

    epoch = source_date_epoch()
    if epoch is not None:
        return datetime.fromtimestamp(epoch, UTC)
    return datetime.now(UTC).replace(microsecond=0)


def parse_date(text: str, option: str = "--date") -> datetime:
    """An ISO 8601 date (``2026-11-28``) or date and time (``2026-11-28T14:03:12+01:00``);
    without a UTC offset it is UTC."""
    try:
        value = datetime.fromisoformat(text.strip())
    except (ValueError, AttributeError):
        raise InputError(f"expected an ISO 8601 date (2026-11-28) or date and time "
                         f"(2026-11-28T14:03:12+01:00), got {text!r}", option=option) from None
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    return value.replace(microsecond=0)


def format_date(value: datetime) -> str:
    """ISO 8601 to the second, with the UTC offset (``+00:00`` for UTC)."""
    return value.isoformat(timespec="seconds")
