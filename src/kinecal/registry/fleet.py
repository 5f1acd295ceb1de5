"""Checks of one robot, or of a fleet on a process pool or a Dask cluster, into the registry.

`check_robot` is the one path every check takes (``kinecal check``, the fleet): the
current calibration is read, today's data judged (`kinecal.registry.check`) and the check
written (`kinecal.registry.store.Registry.record_check`: on PostgreSQL all in one
transaction with the robot's row locked; on SQLite the write makes sure the calibration
judged is still current, else the check is made again on the new one). The record's key
is the serial, the calibration, the date and the data's SHA-256: a check recorded twice
(a task run again after its worker died, a retried transaction whose commit was in fact
done) is stored once.

`check_fleet` runs many robots' checks on any `concurrent.futures.Executor` (the Dask
executor of `kinecal.batch.dask_executor`, a process pool): robots go in chunks, each
worker process keeps one open registry (one connection) for all its chunks, each robot is
one transaction, retried on a conflict (`kinecal.registry.store.RETRIES`); a chunk whose
worker died is run again, its finished robots found by their keys. Every robot's outcome
comes back: its check's id and verdict, or the error that stopped it.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, as_completed
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from kinecal.errors import InputError
from kinecal.registry.check import ALPHA

__all__ = ["FleetCheck", "FleetOutcome", "check_fleet", "check_robot"]

#: robots per task of `check_fleet`
CHUNK = 25
#: calibrations kept ready per worker process
_CACHE = 256
_REGISTRIES: dict[str, Any] = {}
#: keyed by the stored result's and model's SHA-256 (never by a record's id: ids repeat
#: from one registry to another)
_CALIBRATED: OrderedDict[tuple, Any] = OrderedDict()


@dataclass(frozen=True)
class FleetCheck:
    """One robot's check in a fleet: `data` holds file paths or in-memory measurement
    sets (`kinecal.data.Measurements`, `GaugeMeasurements`); the other fields as
    `check_robot`'s."""

    serial: str
    data: tuple
    date: datetime | None = None
    sigma: tuple | None = None
    limit: float | None = None
    alpha: float = ALPHA
    register_base: bool = False
    operator: str | None = None
    instrument: str | None = None
    note: str | None = None
    angle_unit: str | None = None


@dataclass
class FleetOutcome:
    """What happened to one robot of `check_fleet`."""

    serial: str
    id: int | None = None
    verdict: str | None = None
    new: bool = False
    error: str | None = None
    attempts: int = 1
    extra: dict[str, Any] = field(default_factory=dict)


def _data_entry(k: int, d: Any) -> dict[str, Any]:
    """The record's entry of a measurement set: a file's SHA-256, or that of an in-memory
    set's arrays."""
    from kinecal.registry.records import file_entry

    if isinstance(d, str | Path):
        return file_entry(f"DATA {d}", d)
    h = hashlib.sha256()
    for name in ("q", "xyz", "rotations", "weights", "values", "sigma", "marker", "group"):
        v = getattr(d, name, None)
        if v is not None and hasattr(v, "tobytes"):
            h.update(name.encode())
            h.update(v.tobytes())
    return {"name": f"data {k + 1} ({type(d).__name__}, in memory)",
            "path": getattr(d, "source", "") or "", "sha256": h.hexdigest(), "size": 0}


def _calibrated(ev: dict[str, Any], serial: str) -> Any:
    """The stored calibration `ev` ready to check (kept for the next robots)."""
    from kinecal.registry.check import calibrated_from_result
    from kinecal.registry.records import load_stored_model, source_of

    key = (ev["document_sha256"], ev.get("model_sha256"), ev.get("base_link"),
           ev.get("tip_link"))
    cal = _CALIBRATED.get(key)
    if cal is None:
        cal = calibrated_from_result(load_stored_model(source_of(ev)), ev["document"],
                                     f"calibration {ev['id']} of {serial}")
        _CALIBRATED[key] = cal
        while len(_CALIBRATED) > _CACHE:
            _CALIBRATED.popitem(last=False)
    return cal


def check_robot(reg: Any, serial: str, data: Sequence[Any], *,
                sigma: Sequence[float | None] | None = None, limit: float | None = None,
                alpha: float = ALPHA, register_base: bool = False,
                date: datetime | None = None, operator: str | None = None,
                instrument: str | None = None, note: str | None = None,
                command: str | None = None, warnings: Callable[[], list] | None = None,
                attempts: int = 3, angle_unit: str | None = None
                ) -> tuple[dict[str, Any], dict[str, Any], bool]:
    """Check `serial`'s current calibration against `data` and record it (module
    docstring); returns ``(check document, stored event, new)``. `warnings`: the
    diagnostics collected so far, put into the document; `angle_unit`: of the files'
    joint columns (default the model's)."""
    from kinecal.io.kinds import read_kind
    from kinecal.registry.check import run_check
    from kinecal.registry.records import check_row

    inputs = [_data_entry(k, d) for k, d in enumerate(data)]

    def make(ev: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        cal = _calibrated(ev, serial)
        sets = [read_kind(d, cal.model, angle_unit=angle_unit) if isinstance(d, str | Path)
                else d for d in data]
        res = run_check(cal, sets, sigma=list(sigma) if sigma is not None else None,
                        limit=limit, alpha=alpha, register_base=register_base)
        if warnings is not None:
            res.warnings = [w.to_dict() for w in warnings()]
        doc = {**res.to_dict(), "calibration": ev["id"]}
        return doc, check_row(serial, ev["id"], doc, inputs=inputs, date=date,
                              operator=operator, instrument=instrument, note=note,
                              command=command)

    return reg.record_check(serial, make, attempts)


def _registry(db: str) -> Any:
    """This process's open registry at `db` (one connection for all its tasks)."""
    from kinecal.registry.store import open_registry

    reg = _REGISTRIES.get(db)
    if reg is None:
        reg = _REGISTRIES[db] = open_registry(db)
    return reg


def _run_chunk(db: str, checks: list[FleetCheck]) -> list[FleetOutcome]:
    """A task: the checks of a chunk of robots, one transaction each."""
    from kinecal import diagnostics

    reg = _registry(db)
    out = []
    for c in checks:
        try:
            with diagnostics.collect() as found:
                doc, stored, new = check_robot(
                    reg, c.serial, c.data, sigma=c.sigma, limit=c.limit, alpha=c.alpha,
                    register_base=c.register_base, date=c.date, operator=c.operator,
                    instrument=c.instrument, note=c.note, warnings=lambda f=found: list(f),
                    angle_unit=c.angle_unit)
            out.append(FleetOutcome(c.serial, stored["id"], stored["verdict"], new,
                                    extra={"deviation": doc["deviation"]}))
        except (InputError, OSError) as exc:
            out.append(FleetOutcome(c.serial, error=str(exc)))
    return out


def check_fleet(db: str, checks: Sequence[FleetCheck], *, executor: Executor | None = None,
                chunk: int = CHUNK, on_result: Callable[[FleetOutcome], None] | None = None,
                resubmit: int = 2) -> list[FleetOutcome]:
    """Run `checks` (module docstring); outcomes in the order of `checks`.

    `executor`: where the chunks run (None: here, one after the other). `resubmit`: times
    a chunk whose task failed (its worker died) is run again.
    """
    if chunk < 1:
        raise InputError(f"expected a positive chunk size, got {chunk}")
    parts = [list(checks[i:i + chunk]) for i in range(0, len(checks), chunk)]
    results: dict[int, list[FleetOutcome]] = {}
    tries = dict.fromkeys(range(len(parts)), 0)
    if executor is None:
        for i, part in enumerate(parts):
            results[i] = _run_chunk(db, part)
            for o in results[i]:
                if on_result:
                    on_result(o)
    else:
        pending = {executor.submit(_run_chunk, db, part): i for i, part in enumerate(parts)}
        while pending:
            for fut in as_completed(list(pending)):
                i = pending.pop(fut)
                try:
                    results[i] = fut.result()
                except Exception as exc:  # the worker died or the task failed: again
                    tries[i] += 1
                    if tries[i] > resubmit:
                        results[i] = [FleetOutcome(c.serial, error=f"task failed: {exc}",
                                                   attempts=tries[i]) for c in parts[i]]
                    else:
                        pending[executor.submit(_run_chunk, db, parts[i])] = i
                        continue
                for o in results[i]:
                    o.attempts = tries[i] + 1
                    if on_result:
                        on_result(o)
                break
    return [o for i in range(len(parts)) for o in results[i]]
