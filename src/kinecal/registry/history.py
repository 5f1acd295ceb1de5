"""Reading the registry's records: one event, the current calibration, a robot's history
in time order, the fleet's list (queries on an open connection, shared by the store's
reads and writes).

A history (``registry history --json``) is ``{"serial", "events": [...], "current",
"current_changes", "retracted"}``: events in time order (their date, then the order they
were recorded), each ``{"id", "kind": "calibration" | "check", "date", ...}``; a check
has its ``verdict``, ``statistic``, ``p_value``, ``limit``, ``deviation`` and the
``calibration`` it judged, a calibration its ``subject`` (``arm`` or ``handeye``),
``model`` and summary; retracted records are left out unless asked for (then marked).
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["calibration_ids_text", "current_id", "event_by_id", "event_by_uid",
           "history_of", "is_retracted", "robot_rows"]

#: columns of an event read for lists and histories (no document, report or model text)
LIGHT = ("id", "robot_id", "uid", "kind", "subject", "date", "at", "recorded", "kinecal",
         "operator", "instrument", "note", "command", "inputs", "calibration_id",
         "model_name", "model_file", "model_sha256", "base_link", "tip_link", "verdict",
         "statistic", "p_value", "limit_value", "deviation", "summary", "document_sha256",
         "report_name", "report_sha256")
FULL = LIGHT + ("document", "model_text", "report")


def _columns(full: bool) -> list[Any]:
    from kinecal.registry.schema import events

    return [events.c[n] for n in (FULL if full else LIGHT)]


def _row(row: Any) -> dict[str, Any]:
    out = dict(row._mapping)
    for key in ("summary", "inputs"):
        if isinstance(out.get(key), str):
            out[key] = json.loads(out[key])
    if "document" in out and isinstance(out["document"], str):
        out["document"] = json.loads(out["document"])
    return out


def event_by_id(conn: Any, event_id: int, full: bool = False) -> dict[str, Any] | None:
    """The event `event_id` (None if there is none)."""
    import sqlalchemy as sa

    from kinecal.registry.schema import events

    row = conn.execute(sa.select(*_columns(full)).where(events.c.id == event_id)).first()
    return None if row is None else _row(row)


def event_by_uid(conn: Any, uid: str) -> dict[str, Any] | None:
    """The event recorded under the key `uid` (None if there is none)."""
    import sqlalchemy as sa

    from kinecal.registry.schema import events

    row = conn.execute(sa.select(*_columns(False)).where(events.c.uid == uid)).first()
    return None if row is None else _row(row)


def _retracted(conn: Any, robot_id: int | None = None) -> dict[int, dict[str, Any]]:
    import sqlalchemy as sa

    from kinecal.registry.schema import corrections

    query = sa.select(corrections)
    if robot_id is not None:
        query = query.where(corrections.c.robot_id == robot_id)
    return {r.event_id: {"reason": r.reason, "date": r.date, "operator": r.operator,
                         "id": r.id} for r in conn.execute(query.order_by(corrections.c.id))}


def is_retracted(conn: Any, event_id: int) -> bool:
    """Whether `event_id` was retracted."""
    import sqlalchemy as sa

    from kinecal.registry.schema import corrections

    return conn.execute(sa.select(corrections.c.id).where(
        corrections.c.event_id == event_id)).first() is not None


def _changes(conn: Any, robot_id: int | None = None) -> list[Any]:
    import sqlalchemy as sa

    from kinecal.registry.schema import current_changes

    query = sa.select(current_changes)
    if robot_id is not None:
        query = query.where(current_changes.c.robot_id == robot_id)
    return list(conn.execute(query.order_by(current_changes.c.id)))


def _current_of(changes: list[Any], retracted: dict[int, Any]) -> dict[tuple, int]:
    """``{(robot_id, subject): event_id}``: the last change whose event stands."""
    out: dict[tuple, int] = {}
    for ch in changes:
        if ch.event_id not in retracted:
            out[(ch.robot_id, ch.subject)] = ch.event_id
    return out


def current_id(conn: Any, robot_id: int, subject: str = "arm") -> int | None:
    """The current `subject` calibration of robot `robot_id` (None: none)."""
    cur = _current_of(_changes(conn, robot_id), _retracted(conn, robot_id))
    return cur.get((robot_id, subject))


def calibration_ids_text(conn: Any, robot_id: int) -> str:
    """``3, 7, 12`` (or ``none``): a robot's calibration ids, for messages."""
    import sqlalchemy as sa

    from kinecal.registry.schema import events

    ids = [r[0] for r in conn.execute(sa.select(events.c.id).where(
        events.c.robot_id == robot_id, events.c.kind == "calibration").order_by(events.c.id))]
    return ", ".join(map(str, ids)) or "none"


def _public(ev: dict[str, Any], current: dict[tuple, int]) -> dict[str, Any]:
    """An event as the history JSON shows it (module docstring)."""
    out: dict[str, Any] = {"id": ev["id"], "kind": ev["kind"], "date": ev["date"]}
    if ev["kind"] == "check":
        out.update(verdict=ev["verdict"], statistic=ev["statistic"], p_value=ev["p_value"],
                   limit=ev["limit_value"], deviation=ev["deviation"],
                   calibration=ev["calibration_id"])
    else:
        out.update(subject=ev["subject"], model=ev["model_name"],
                   current=current.get((ev["robot_id"], ev["subject"])) == ev["id"])
    for key in ("operator", "instrument", "note"):
        if ev.get(key):
            out[key] = ev[key]
    out["summary"] = ev["summary"]
    out["recorded"] = ev["recorded"]
    out["kinecal"] = ev["kinecal"]
    if ev.get("command"):
        out["command"] = ev["command"]
    out["inputs"] = ev["inputs"]
    if ev.get("report_name"):
        out["report"] = {"name": ev["report_name"], "sha256": ev["report_sha256"]}
    return out


def history_of(conn: Any, serial: str, retracted: bool = False) -> dict[str, Any]:
    """The history of `serial` (module docstring)."""
    import sqlalchemy as sa

    from kinecal.registry.schema import events, robots

    rid = conn.execute(sa.select(robots.c.id).where(robots.c.serial == serial)).scalar()
    gone = _retracted(conn, rid)
    changes = _changes(conn, rid)
    current = _current_of(changes, gone)
    rows = conn.execute(sa.select(*_columns(False)).where(events.c.robot_id == rid)
                        .order_by(events.c.at, events.c.id))
    evs = []
    for row in rows:
        ev = _row(row)
        if ev["id"] in gone and not retracted:
            continue
        pub = _public(ev, current)
        if ev["id"] in gone:
            pub["retracted"] = gone[ev["id"]]
        evs.append(pub)
    return {
        "serial": serial,
        "events": evs,
        "current": {subject: eid for (_, subject), eid in sorted(current.items())},
        "current_changes": [{"calibration": c.event_id, "subject": c.subject, "date": c.date,
                             "reason": c.reason, "operator": c.operator} for c in changes],
        "retracted": [{"id": eid, **info} for eid, info in gone.items()],
    }


def robot_rows(conn: Any) -> list[dict[str, Any]]:
    """Every robot: serial, counts, current arm calibration, last check (fleet list)."""
    import sqlalchemy as sa

    from kinecal.registry.schema import events, robots

    gone = _retracted(conn)
    current = _current_of(_changes(conn), gone)
    cols = [events.c[n] for n in ("id", "robot_id", "kind", "subject", "date", "at",
                                  "verdict", "deviation", "limit_value", "model_name",
                                  "summary", "calibration_id")]
    per: dict[int, dict[str, Any]] = {}
    for rid, serial, created in conn.execute(sa.select(robots.c.id, robots.c.serial,
                                                       robots.c.created)):
        per[rid] = {"serial": serial, "created": created, "calibrations": 0, "checks": 0,
                    "current": None, "last_check": None, "model": None, "deviations": []}
    for row in conn.execute(sa.select(*cols).order_by(events.c.at, events.c.id)):
        if row.id in gone:
            continue
        entry = per[row.robot_id]
        if row.kind == "calibration":
            entry["calibrations"] += 1
            if current.get((row.robot_id, row.subject)) == row.id and row.subject == "arm":
                entry["current"] = {"id": row.id, "date": row.date, "at": row.at}
                entry["model"] = row.model_name
        else:
            entry["checks"] += 1
            entry["last_check"] = {"id": row.id, "date": row.date, "verdict": row.verdict,
                                   "deviation": row.deviation, "limit": row.limit_value}
            entry["deviations"].append((row.at, row.deviation, row.limit_value,
                                        row.calibration_id))
    return sorted(per.values(), key=lambda e: e["serial"])
