"""Connections to a registry: the SQLAlchemy engine of each backend, its transactions, and
the database's errors said in a user's words.

SQLite: one file, no connection pool (each command or worker holds one connection); a
write takes the file's write lock at its start (``BEGIN IMMEDIATE``), so that concurrent
writers queue (for up to `BUSY_SECONDS`) instead of failing half-way; foreign keys on.
A read-only file is opened read-only (``mode=ro``). PostgreSQL: psycopg 3, one connection
per engine (a Dask worker keeps its own), ``READ COMMITTED`` with the robot's row locked by
each write (`kinecal.registry.store`).

`translate` turns the drivers' errors into `InputError` (a read-only registry, a damaged
file, a server that cannot be reached: exit 2) or `OSError` with the disk's errno (a full
disk: exit 1), each naming the registry and saying that nothing was recorded.
"""

from __future__ import annotations

import errno
from typing import Any

from kinecal.errors import InputError
from kinecal.registry.location import Location

__all__ = ["BUSY_SECONDS", "is_retryable", "make_engine", "translate"]

#: how long a writer waits for another one's lock on an SQLite registry
BUSY_SECONDS = 120.0
#: PostgreSQL error classes worth a retry: serialization failure, deadlock, unique
#: violation (two writers creating one robot), lock not available
_PG_RETRY = {"40001", "40P01", "23505", "55P03"}


def make_engine(loc: Location, read_only: bool = False) -> Any:
    """The engine of `loc` (module docstring)."""
    import sqlalchemy as sa
    from sqlalchemy.pool import NullPool

    if loc.backend == "postgresql":
        import importlib.util

        if importlib.util.find_spec("psycopg") is None:
            raise InputError("a PostgreSQL registry needs psycopg 3: pip install "
                             "'kinecal[registry]'", option="--db")
        engine = sa.create_engine(loc.target, pool_size=1, max_overflow=0,
                                  pool_pre_ping=True, connect_args={"connect_timeout": 20})
        return engine
    target = loc.target
    if read_only:
        from urllib.parse import quote

        engine = sa.create_engine(f"sqlite:///file:{quote(target)}?mode=ro&uri=true",
                                  poolclass=NullPool, connect_args={"timeout": BUSY_SECONDS})
    else:
        engine = sa.create_engine(f"sqlite:///{target}", poolclass=NullPool,
                                  connect_args={"timeout": BUSY_SECONDS})

    @sa.event.listens_for(engine, "connect")
    def _connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # transactions begun by `_begin` alone
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.close()

    @sa.event.listens_for(engine, "begin")
    def _begin(conn: Any) -> None:
        write = conn.get_execution_options().get("kinecal_write", False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")

    return engine


def _pg_code(exc: BaseException) -> str | None:
    orig = getattr(exc, "orig", None)
    return getattr(orig, "sqlstate", None) or getattr(orig, "pgcode", None)


def is_retryable(exc: BaseException) -> bool:
    """A conflict between concurrent writers (worth the transaction again)."""
    code = _pg_code(exc)
    if code is not None:
        return code in _PG_RETRY
    text = str(getattr(exc, "orig", exc)).lower()
    return "database is locked" in text or "database is busy" in text


def translate(exc: BaseException, loc: Location, write: bool) -> BaseException:
    """`exc` (a DBAPI error) as the error the user reads (module docstring)."""
    orig = getattr(exc, "orig", exc)
    text = " ".join(str(orig).split())
    low = text.lower()
    where = loc.shown
    nothing = "nothing was recorded, the registry is as it was" if write else "nothing read"
    code = _pg_code(exc)
    if "disk is full" in low or code in ("53100", "53200") or "no space" in low:
        return OSError(errno.ENOSPC, f"disk full ({nothing})", where)
    if "disk i/o error" in low or code == "58030":
        return OSError(errno.EIO, f"disk I/O error ({nothing})", where)
    if "readonly" in low or "read-only" in low or code == "25006":
        return InputError(f"the registry is read-only ({nothing}): give a writable copy with "
                          "--db, or ask for write access", file=where)
    if "malformed" in low or "not a database" in low or "corrupt" in low:
        return InputError(f"the registry file is damaged (SQLite: {text}); kinecal leaves it "
                          "as it is: restore a backup, or recover what is readable with "
                          f"sqlite3 {where} .recover", file=where)
    if "unable to open database file" in low:
        return InputError("cannot open the registry file here (its folder must exist and be "
                          "writable: SQLite writes a journal beside it)", file=where)
    if "database is locked" in low:
        return InputError(f"another process has held the registry's lock for over "
                          f"{BUSY_SECONDS:.0f} s ({nothing}); try again", file=where)
    if code is None and loc.backend == "postgresql" and (
            "connection" in low or "could not" in low or "password" in low):
        return InputError(f"cannot connect to the PostgreSQL registry: {text}", file=where)
    if code is not None and code.startswith(("08", "28", "3D")):
        return InputError(f"cannot use the PostgreSQL registry: {text}", file=where)
    return exc
