"""Opening a registry safely: the file checks before SQLite touches it, the schema version
read (a newer kinecal's registry refused with its version), and the migrations when the
schema is older or absent (`kinecal.registry.store` docstring)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from kinecal.errors import InputError
from kinecal.registry.location import Location

__all__ = ["QUICK_CHECK_BYTES", "SQLITE_MAGIC", "check_and_migrate", "prepare"]

#: the first 16 bytes of every SQLite 3 database file
SQLITE_MAGIC = b"SQLite format 3\x00"
#: a registry file up to this size gets SQLite's quick check before it is written
QUICK_CHECK_BYTES = 512 * 1024 * 1024


def prepare(loc: Location, write: bool) -> bool:
    """Check an SQLite file before it is opened; True when it must be opened read-only.

    Raises `InputError` for a missing registry that is only to be read, a folder, a file
    that is not an SQLite database (it is never written), and a registry to be written
    that is read-only (the file, or its folder, where SQLite writes its journal).
    """
    if loc.backend != "sqlite":
        return False
    path = loc.path
    if path.is_dir():
        raise InputError(f"{path} is a folder, expected the registry file (e.g. "
                         f"{Path(path, 'kinecal.db')})", option=loc.option)
    if not path.exists():
        if not write:
            raise InputError(f"no registry at {path} (nothing is registered yet: kinecal "
                             "registry add SERIAL RESULT.json, or calibrate ... --register "
                             "SERIAL, makes it; --db or $KINECAL_DB name another)",
                             option=loc.option)
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise InputError(f"folder {folder} does not exist", option=loc.option)
        if not os.access(folder, os.W_OK | os.X_OK):
            raise InputError(f"folder {folder} is not writable: cannot make the registry "
                             "there (nothing was recorded)", option=loc.option)
        return False
    if not path.is_file():
        raise InputError(f"{path} is not a regular file, expected the registry file",
                         option=loc.option)
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(SQLITE_MAGIC))
    except OSError as exc:
        raise InputError(f"cannot read the registry: {exc.strerror}", file=path) from None
    if (head and head != SQLITE_MAGIC[:len(head)]) or 0 < len(head) < len(SQLITE_MAGIC):
        raise InputError("not an SQLite database, so not a kinecal registry (its first bytes "
                         "say otherwise); kinecal leaves it as it is: name the registry with "
                         "--db, or restore it from a backup", file=path)
    writable = os.access(path, os.W_OK) and os.access(path.parent if str(path.parent)
                                                      else Path("."), os.W_OK | os.X_OK)
    if write and not writable:
        raise InputError("the registry is read-only (nothing was recorded): give a writable "
                         "copy with --db, or ask for write access (SQLite also writes a "
                         "journal in the file's folder)", file=path)
    return not writable


def _tables(conn: Any, backend: str) -> set[str]:
    if backend == "sqlite":
        rows = conn.exec_driver_sql("SELECT name FROM sqlite_master WHERE type = 'table'")
    else:
        rows = conn.exec_driver_sql(
            "SELECT table_name FROM information_schema.tables "
            "WHERE table_schema = current_schema()")
    return {r[0] for r in rows}


def _state(conn: Any, backend: str) -> tuple[set[str], str | None]:
    tables = _tables(conn, backend)
    version = None
    if "alembic_version" in tables:
        version = conn.exec_driver_sql("SELECT version_num FROM alembic_version").scalar()
    return tables, version


def _info(conn: Any, tables: set[str]) -> dict[str, str]:
    if "registry_info" not in tables:
        return {}
    return {k: v for k, v in conn.exec_driver_sql("SELECT key, value FROM registry_info")}


def _refuse_unknown(loc: Location, conn: Any, tables: set[str], version: str | None) -> None:
    from kinecal import __version__
    from kinecal.registry.schema import REVISIONS, SCHEMA_VERSION

    if version is None and tables - {"alembic_version"}:
        some = ", ".join(sorted(tables)[:4])
        raise InputError(f"a database with tables of its own ({some}...) and no kinecal "
                         "registry in it; kinecal leaves it as it is: name another with --db",
                         file=loc.shown)
    if version is not None and version not in REVISIONS:
        info = _info(conn, tables)
        raise InputError(
            f"the registry was written by kinecal {info.get('kinecal', '(unknown version)')} "
            f"(registry schema {info.get('schema', '?')}, revision {version}); this kinecal "
            f"{__version__} reads schema {SCHEMA_VERSION} at most: upgrade kinecal. "
            "The registry is left as it is", file=loc.shown)


def check_and_migrate(reg: Any, write: bool) -> None:
    """Refuse what this kinecal cannot read; bring an older or empty registry to its
    schema (in one write transaction, under a lock so that concurrent first writers
    migrate once)."""
    from kinecal.registry.schema import HEAD

    loc = reg.location
    with reg.engine.connect() as conn, conn.begin():
        tables, version = _state(conn, loc.backend)
        _refuse_unknown(loc, conn, tables, version)
        if version == HEAD:
            if write and loc.backend == "sqlite":
                _quick_check(conn, loc)
            return
    if not write:
        raise InputError(f"the registry has schema revision {version or 'none'}, older than "
                         "this kinecal's: open it once for writing (any registry add) to "
                         "upgrade it", file=loc.shown)

    def migrate(conn: Any) -> None:
        if loc.backend == "postgresql":  # one migrating process at a time
            conn.exec_driver_sql("SELECT pg_advisory_xact_lock(7262815201)")
        tables, version = _state(conn, loc.backend)
        _refuse_unknown(loc, conn, tables, version)
        if version != HEAD:
            _upgrade(conn)

    reg.write(migrate)


def _quick_check(conn: Any, loc: Location) -> None:
    if os.path.getsize(loc.path) > QUICK_CHECK_BYTES:
        return
    found = [r[0] for r in conn.exec_driver_sql("PRAGMA quick_check")]
    if found != ["ok"]:
        raise InputError(f"the registry file is damaged (SQLite's quick check: {found[0]}"
                         f"{' ...' if len(found) > 1 else ''}); kinecal leaves it as it is: "
                         f"restore a backup, or recover what is readable with sqlite3 "
                         f"{loc.shown} .recover", file=loc.shown)


def _upgrade(conn: Any) -> None:
    """Run the migrations up to the head on `conn` (in its transaction), then record the
    schema and the kinecal that wrote it."""
    from alembic import command
    from alembic.config import Config

    from kinecal import __version__
    from kinecal.registry.schema import SCHEMA_VERSION, registry_info

    cfg = Config()
    cfg.set_main_option("script_location", str(Path(__file__).with_name("migrations")))
    cfg.attributes["connection"] = conn
    command.upgrade(cfg, "head")
    conn.execute(registry_info.delete())
    conn.execute(registry_info.insert(), [
        {"key": "schema", "value": str(SCHEMA_VERSION)},
        {"key": "kinecal", "value": __version__},
    ])
