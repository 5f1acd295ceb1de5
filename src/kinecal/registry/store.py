"""The store: `open_registry` and the `Registry` it returns (reads and append-only writes).

Opening checks, before anything is written (`kinecal.registry.opening`): an SQLite file
is an SQLite database (the first bytes) and passes SQLite's quick check when it is to be
written; a registry written by a newer kinecal (an Alembic revision this one does not
know) is refused with that kinecal's version and schema; a database with tables of its
own but no registry is refused; an older or new registry is brought to this kinecal's
schema by the migrations, inside one transaction.

Every write is one transaction: a calibration or check row, the change of the current
calibration that goes with it, a retraction; on PostgreSQL the robot's row is locked for
the transaction (concurrent writers of one robot queue; creating one robot twice at once
is a unique violation, retried), on SQLite the file's write lock is taken at the start.
A transaction that meets a conflict (serialization failure, deadlock) is run again, up to
`RETRIES` times. Records carry a unique key (``uid``): writing a record whose key is
already stored writes nothing, so a retried task can never record twice.
"""

from __future__ import annotations

import json
import random
import time
from collections.abc import Callable
from datetime import datetime
from typing import Any

from kinecal.errors import InputError
from kinecal.registry.engine import is_retryable, make_engine, translate
from kinecal.registry.location import Location, format_date, locate, now

__all__ = ["RETRIES", "Registry", "open_registry"]

#: runs of a write transaction that meets a conflict
RETRIES = 12


def open_registry(db: str | None = None, *, write: bool = True) -> Registry:
    """The registry at `db` (a path or URL; ``$KINECAL_DB`` or ``kinecal.db`` when None).

    `write`: the caller will write (the file is created when missing and must be
    writable); else it is opened read-only, and a missing file is an error.
    """
    from kinecal.registry.opening import prepare

    _require_extra()
    loc = locate(db)
    read_only = prepare(loc, write)
    engine = make_engine(loc, read_only=read_only)
    reg = Registry(loc, engine, read_only)
    try:
        reg._open(write)
    except BaseException:
        reg.close()
        raise
    return reg


def _require_extra() -> None:
    """`InputError` naming the optional extra when SQLAlchemy or Alembic is missing."""
    import importlib.util

    missing = [m for m in ("sqlalchemy", "alembic") if importlib.util.find_spec(m) is None]
    if missing:
        raise InputError(f"the registry needs {' and '.join(missing)}: pip install "
                         "'kinecal[registry]' (PostgreSQL: psycopg, in the same extra)",
                         option="--db")


class Registry:
    """An open registry (`open_registry`); use it as a context manager or `close` it."""

    def __init__(self, loc: Location, engine: Any, read_only: bool) -> None:
        self.location = loc
        self.engine = engine
        self.read_only = read_only

    # ---------------------------------------------------------------- plumbing
    def close(self) -> None:
        """Release the connection(s)."""
        self.engine.dispose()

    def __enter__(self) -> Registry:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _open(self, write: bool) -> None:
        from kinecal.registry.opening import check_and_migrate

        self._call(lambda: check_and_migrate(self, write), write=write)

    def _call(self, fn: Callable[[], Any], write: bool) -> Any:
        import sqlalchemy as sa

        try:
            return fn()
        except sa.exc.DBAPIError as exc:
            raise translate(exc, self.location, write) from None

    def read(self, fn: Callable[[Any], Any]) -> Any:
        """``fn(connection)`` in one read transaction."""
        def run() -> Any:
            with self.engine.connect() as conn, conn.begin():
                return fn(conn)
        return self._call(run, write=False)

    def write(self, fn: Callable[[Any], Any]) -> Any:
        """``fn(connection)`` in one write transaction, run again on a conflict."""
        import sqlalchemy as sa

        if self.read_only:
            raise InputError("the registry is read-only (nothing was recorded): give a "
                             "writable copy with --db, or ask for write access",
                             file=self.location.shown)
        for attempt in range(RETRIES):
            try:
                with self.engine.connect() as conn:
                    conn.execution_options(kinecal_write=True)
                    with conn.begin():
                        return fn(conn)
            except sa.exc.DBAPIError as exc:
                retry = is_retryable(exc) and attempt + 1 < RETRIES and (
                    self.location.backend == "postgresql")
                if not retry:
                    raise translate(exc, self.location, True) from None
                time.sleep(min(0.5, 0.005 * 2 ** attempt) * (0.5 + random.random()))
        raise AssertionError("unreachable")  # pragma: no cover

    # ---------------------------------------------------------------- robots
    def _robot_id(self, conn: Any, serial: str, create: bool, lock: bool) -> int | None:
        """The robot's id (its row locked on PostgreSQL when `lock`); created if asked."""
        import sqlalchemy as sa

        from kinecal.registry.schema import robots

        query = sa.select(robots.c.id).where(robots.c.serial == serial)
        if lock and self.location.backend == "postgresql":
            query = query.with_for_update()
        rid = conn.execute(query).scalar()
        if rid is None and create:
            rid = conn.execute(robots.insert().values(
                serial=serial, created=format_date(now()))).inserted_primary_key[0]
        return rid

    def serials(self) -> list[str]:
        """Every serial number, sorted."""
        import sqlalchemy as sa

        from kinecal.registry.schema import robots

        return self.read(lambda c: [r[0] for r in c.execute(
            sa.select(robots.c.serial).order_by(robots.c.serial))])

    def require(self, serial: str) -> None:
        """`InputError` when `serial` has no record."""
        if serial not in set(self._serials_like(serial)):
            known = self.serials()
            hint = f" (robots: {', '.join(known[:5])}{', ...' if len(known) > 5 else ''})" \
                if known else " (the registry is empty)"
            raise InputError(f"no robot {serial!r} in the registry {self.location.shown}"
                             f"{hint}", option="SERIAL")

    def _serials_like(self, serial: str) -> list[str]:
        import sqlalchemy as sa

        from kinecal.registry.schema import robots

        return self.read(lambda c: [r[0] for r in c.execute(
            sa.select(robots.c.serial).where(robots.c.serial == serial))])

    # ---------------------------------------------------------------- writes
    def add_event(self, serial: str, row: dict[str, Any], *, current: str | None = None,
                  reason: str | None = None, on_duplicate: str = "refuse",
                  check_current: int | None = None) -> tuple[dict[str, Any], bool]:
        """Store one calibration or check (`row`: the ``events`` columns but the ids), in
        one transaction; returns ``(event, new)``.

        `current`: make the new calibration current for this subject (``arm``,
        ``handeye``), the change recorded with `reason`. `on_duplicate`: when a record
        with the same ``uid`` exists, ``refuse`` (`InputError` naming it) or ``return``
        it (``new`` False). `check_current`: the calibration a check judged; the write is
        refused (`StaleCalibration`) when another one has become current meanwhile.
        """
        from kinecal.registry import history as hist

        def txn(conn: Any) -> tuple[dict[str, Any], bool]:
            rid = self._robot_id(conn, serial, create=True, lock=True)
            if check_current is not None:
                now_current = hist.current_id(conn, rid, row["subject"])
                if now_current != check_current:
                    raise StaleCalibration(check_current, now_current)
            return self._insert(conn, rid, serial, row, current, reason, on_duplicate)

        return self.write(txn)

    def _insert(self, conn: Any, rid: int, serial: str, row: dict[str, Any],
                current: str | None, reason: str | None, on_duplicate: str
                ) -> tuple[dict[str, Any], bool]:
        """Insert `row` for robot `rid` in the open transaction (`add_event`)."""
        from kinecal.registry import history as hist
        from kinecal.registry.schema import current_changes, events

        old = hist.event_by_uid(conn, row["uid"])
        if old is not None:
            if on_duplicate == "return":
                return old, False
            raise InputError(
                f"this {old['kind']} is already in the registry as {old['kind']} "
                f"{old['id']} of {serial} ({old['date']}): nothing was added; to record "
                "it once more give --force and a --reason", option="RESULT")
        eid = conn.execute(events.insert().values(robot_id=rid, **row)).inserted_primary_key[0]
        if current is not None:
            conn.execute(current_changes.insert().values(
                robot_id=rid, event_id=eid, subject=current, date=row["date"],
                recorded=row["recorded"], reason=reason, operator=row.get("operator")))
        return hist.event_by_id(conn, eid), True

    def record_check(self, serial: str, make: Callable[[dict[str, Any]], tuple[Any, dict]],
                     attempts: int = 3) -> tuple[Any, dict[str, Any], bool]:
        """Judge and record a check of `serial`'s current arm calibration: ``make(event)``
        (the current calibration with its document and model) returns ``(document,
        row)``; returns ``(document, stored event, new)``; a row whose key is stored
        already is not stored again (``new`` False).

        PostgreSQL: one transaction, the robot's row locked from reading its current
        calibration to writing the check (other robots go on; a second check of this robot
        waits). SQLite, whose write lock is the whole file's: the current calibration is
        read, the check made outside any lock, and written in a transaction that makes
        sure the calibration is still current (else made again, up to `attempts` times);
        when other writers kept changing it, a last attempt holds the file's write lock
        from reading to writing, as PostgreSQL's row lock does.
        """
        from kinecal.registry import history as hist

        def txn(conn: Any) -> tuple[Any, dict[str, Any], bool]:
            rid = self._robot_id(conn, serial, create=False, lock=True)
            if rid is None:  # (no second connection: one per process on PostgreSQL)
                raise InputError(f"no robot {serial!r} in the registry "
                                 f"{self.location.shown}", option="SERIAL")
            eid = hist.current_id(conn, rid, "arm")
            if eid is None:
                raise InputError(f"{serial} has no current arm calibration (registry add "
                                 f"{serial} RESULT.json records one)", option="SERIAL")
            doc, row = make(hist.event_by_id(conn, eid, full=True))
            stored, new = self._insert(conn, rid, serial, row, None, None, "return")
            return doc, stored, new

        if self.location.backend == "postgresql":
            return self.write(txn)
        for _ in range(attempts):
            ev = self.current(serial)
            doc, row = make(ev)
            try:
                stored, new = self.add_event(serial, row, check_current=ev["id"],
                                             on_duplicate="return")
                return doc, stored, new
            except StaleCalibration:
                continue
        return self.write(txn)  # BEGIN IMMEDIATE: no other writer until it is stored

    def set_current(self, serial: str, event_id: int, *, reason: str | None = None,
                    operator: str | None = None, date: datetime | None = None
                    ) -> dict[str, Any]:
        """Make calibration `event_id` of `serial` current (a new row: the history of which
        calibration was current is kept)."""
        from kinecal.registry import history as hist
        from kinecal.registry.schema import current_changes

        self.require(serial)
        when = format_date(date or now())

        def txn(conn: Any) -> dict[str, Any]:
            rid = self._robot_id(conn, serial, create=False, lock=True)
            ev = hist.event_by_id(conn, event_id)
            if ev is None or ev["robot_id"] != rid or ev["kind"] != "calibration":
                raise InputError(f"{serial} has no calibration {event_id} (its calibrations: "
                                 f"{hist.calibration_ids_text(conn, rid)})", option="ID")
            if hist.is_retracted(conn, event_id):
                raise InputError(f"calibration {event_id} of {serial} was retracted: it "
                                 "cannot be current", option="ID")
            if hist.current_id(conn, rid, ev["subject"]) == event_id:
                raise InputError(f"calibration {event_id} is {serial}'s current "
                                 f"{ev['subject']} calibration already: nothing changed",
                                 option="ID")
            conn.execute(current_changes.insert().values(
                robot_id=rid, event_id=event_id, subject=ev["subject"], date=when,
                recorded=format_date(now()), reason=reason, operator=operator))
            return ev

        return self.write(txn)

    def retract(self, serial: str, event_id: int, *, reason: str,
                operator: str | None = None) -> dict[str, Any]:
        """Take calibration or check `event_id` out of `serial`'s history, with `reason`
        (kept: ``registry show`` lists retractions; nothing is deleted)."""
        from kinecal.registry import history as hist
        from kinecal.registry.schema import corrections

        if not reason or not reason.strip():
            raise InputError("a retraction needs its reason", option="--reason")
        self.require(serial)

        def txn(conn: Any) -> dict[str, Any]:
            rid = self._robot_id(conn, serial, create=False, lock=True)
            ev = hist.event_by_id(conn, event_id)
            if ev is None or ev["robot_id"] != rid:
                raise InputError(f"{serial} has no record {event_id}", option="ID")
            if hist.is_retracted(conn, event_id):
                raise InputError(f"record {event_id} of {serial} is retracted already",
                                 option="ID")
            stamp = format_date(now())
            conn.execute(corrections.insert().values(
                robot_id=rid, event_id=event_id, action="retract", reason=reason.strip(),
                date=stamp, recorded=stamp, operator=operator))
            return ev

        return self.write(txn)

    # ---------------------------------------------------------------- reads
    def history(self, serial: str, *, retracted: bool = False) -> dict[str, Any]:
        """`serial`'s records in time order (`kinecal.registry.history.history_of`)."""
        from kinecal.registry.history import history_of

        self.require(serial)
        return self.read(lambda c: history_of(c, serial, retracted))

    def current(self, serial: str, subject: str = "arm") -> dict[str, Any]:
        """The current `subject` calibration of `serial`, with its document and model."""
        from kinecal.registry import history as hist

        def get(conn: Any) -> tuple[bool, dict[str, Any] | None]:
            rid = self._robot_id(conn, serial, create=False, lock=False)
            if rid is None:
                return False, None
            eid = hist.current_id(conn, rid, subject)
            return True, None if eid is None else hist.event_by_id(conn, eid, full=True)

        known, ev = self.read(get)
        if not known:
            self.require(serial)
        if ev is None:
            raise InputError(f"{serial} has no current {subject} calibration (registry add "
                             f"{serial} RESULT.json records one)", option="SERIAL")
        return ev

    def event(self, event_id: int, full: bool = False) -> dict[str, Any] | None:
        """One record by id (`full`: with document, model and report)."""
        from kinecal.registry import history as hist

        return self.read(lambda c: hist.event_by_id(c, event_id, full=full))

    def robots(self) -> list[dict[str, Any]]:
        """Every robot with its counts, current calibration and last check."""
        from kinecal.registry.history import robot_rows

        return self.read(robot_rows)


class StaleCalibration(InputError):
    """The calibration a check judged is no longer current (another process changed it)."""

    def __init__(self, judged: int, current: int | None) -> None:
        self.judged, self.current = judged, current
        super().__init__(f"calibration {judged} stopped being current while the check ran "
                         f"(now {current}); run the check again")


def dumps(obj: Any) -> str:
    """Canonical JSON of a stored document (sorted keys, no NaN)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)
