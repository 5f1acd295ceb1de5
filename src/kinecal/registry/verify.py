"""``registry verify``: is the registry sound? SQLite's full integrity check (an SQLite
file), every record's key unique, every check's calibration and every current change's
calibration a calibration of the same robot, every stored document's SHA-256 right."""

from __future__ import annotations

import hashlib
from typing import Any

__all__ = ["verify_registry"]


def verify_registry(reg: Any) -> tuple[list[str], dict[str, int]]:
    """``(problems, counts)``: what is wrong (empty when sound) and how many rows of each
    table were read."""
    import sqlalchemy as sa

    from kinecal.registry.schema import corrections, current_changes, events, robots

    def run(conn: Any) -> tuple[list[str], dict[str, int]]:
        problems: list[str] = []
        if reg.location.backend == "sqlite":
            found = [r[0] for r in conn.exec_driver_sql("PRAGMA integrity_check")]
            if found != ["ok"]:
                problems += [f"SQLite integrity check: {f}" for f in found[:10]]
        owner: dict[int, tuple[int, str]] = {}
        links = []
        n_events = 0
        for row in conn.execute(sa.select(events.c.id, events.c.robot_id, events.c.kind,
                                          events.c.calibration_id, events.c.document,
                                          events.c.document_sha256)):
            n_events += 1
            owner[row.id] = (row.robot_id, row.kind)
            digest = hashlib.sha256(row.document.encode("utf-8")).hexdigest()
            if digest != row.document_sha256:
                problems.append(f"record {row.id}: its document does not match its SHA-256")
            if row.kind == "check":
                links.append((row.id, row.robot_id, row.calibration_id))
        for eid, rid, cal in links:
            if owner.get(cal, (None, None)) != (rid, "calibration"):
                problems.append(f"check {eid}: its calibration {cal} is not one of the "
                                "robot's")
        for table, name in ((current_changes, "current change"), (corrections,
                                                                  "retraction")):
            for row in conn.execute(sa.select(table.c.id, table.c.robot_id,
                                              table.c.event_id)):
                if owner.get(row.event_id, (None,))[0] != row.robot_id:
                    problems.append(f"{name} {row.id}: record {row.event_id} is not the "
                                    "robot's")
        counts = {"robots": conn.execute(sa.select(sa.func.count()).select_from(robots))
                  .scalar(), "records": n_events}
        return problems, counts

    return reg.read(run)
