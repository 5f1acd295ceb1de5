"""The rows the registry stores: a calibration from its result JSON (with the model it was
calibrated from, its report and the SHA-256 of its inputs), a check from its findings;
and a stored model read back.

A calibration record keeps the model file's text (a bundled model's too), so that it can
be checked and exported years later whatever happened to the file. Its key (``uid``) is
the SHA-256 of the serial number and the result: the same result registered twice for one
robot is refused (`kinecal.registry.store`) unless forced, with a reason.
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from kinecal.errors import InputError
from kinecal.registry.location import format_date, now

__all__ = ["MAX_REPORT_BYTES", "ModelSource", "calibration_row", "check_row", "file_entry",
           "load_stored_model", "model_source", "result_subject", "sha256_bytes"]

#: largest report kept in a record
MAX_REPORT_BYTES = 64 * 1024 * 1024
#: largest model file kept
MAX_MODEL_BYTES = 16 * 1024 * 1024


def sha256_bytes(data: bytes) -> str:
    """SHA-256 (hex) of `data`."""
    return hashlib.sha256(data).hexdigest()


def file_entry(name: str, path: str | Path) -> dict[str, Any]:
    """``{name, path, sha256, size}`` of an input file (read in 1 MiB blocks)."""
    path = Path(path)
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(1 << 20):
            h.update(block)
    return {"name": name, "path": str(path), "sha256": h.hexdigest(),
            "size": path.stat().st_size}


@dataclass(frozen=True)
class ModelSource:
    """The model a calibration was made from, as stored.

    Attributes
    ----------
    name : str
        The model's name (the result's ``model``).
    file : str
        The file's name (``ur5.yaml`` for a bundled model).
    text : str
        Its content.
    base_link, tip_link : str or None
        A URDF's chain ends.
    """

    name: str
    file: str
    text: str
    base_link: str | None = None
    tip_link: str | None = None

    @property
    def sha256(self) -> str:
        return sha256_bytes(self.text.encode("utf-8"))


def model_source(spec: str | None, data: dict, base_link: str | None = None,
                 tip_link: str | None = None) -> ModelSource:
    """The model of a result: `spec` (bundled name, model YAML, URDF), or the bundled
    model the result names."""
    from kinecal.io.bundled import input_file
    from kinecal.io.models import bundled_models

    if spec is None:
        name = data.get("model")
        if name not in bundled_models():
            raise InputError(f"the result is of model {name!r}, not a bundled one: give "
                             "--model (the model file or URDF it was calibrated from)",
                             option="--model")
        spec = str(name)
    path = input_file(spec)
    if path is None or not Path(path).is_file():
        raise InputError(f"no model {spec!r}: expected a bundled name, a model YAML or a URDF",
                         option="--model")
    path = Path(path)
    if path.stat().st_size > MAX_MODEL_BYTES:
        raise InputError(f"a model file of {path.stat().st_size} bytes: at most "
                         f"{MAX_MODEL_BYTES}", file=path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the model: {exc}", file=path) from None
    return ModelSource(str(data.get("model") or path.stem), path.name, text, base_link,
                       tip_link)


def load_stored_model(source: ModelSource) -> Any:
    """The `SerialModel` of a stored model (its text written to a temporary file)."""
    from kinecal.io.models import load_model

    with tempfile.TemporaryDirectory(prefix="kinecal-model-") as tmp:
        path = Path(tmp) / (Path(source.file).name or "model.yaml")
        path.write_text(source.text, encoding="utf-8")
        try:
            return load_model(path, base_link=source.base_link, tip_link=source.tip_link)
        except InputError as exc:
            raise InputError(f"the stored model {source.file} does not load: {exc.message}"
                             ) from None


def source_of(event: dict[str, Any]) -> ModelSource:
    """The `ModelSource` of a stored calibration."""
    return ModelSource(event["model_name"], event["model_file"], event["model_text"],
                       event.get("base_link"), event.get("tip_link"))


def result_subject(data: Any, where: str | Path) -> str:
    """``arm`` (a serial arm's calibration) or ``handeye``; `InputError` otherwise."""
    if isinstance(data, dict) and "X" in data and "setup" in data:
        return "handeye"
    from kinecal.io.result_values import serial_result_parameters

    serial_result_parameters(data, Path(where))  # names a Stewart result as such
    return "arm"


def _arm_summary(data: dict) -> dict[str, Any]:
    cal = data.get("calibration") or {}
    val = data.get("validation") or {}
    out = {"method": data.get("method"), "n": cal.get("n"), "rank": data.get("rank"),
           "free": len(data.get("free") or []), "length_unit": data.get("length_unit"),
           "rms": (cal.get("after") or {}).get("rms"),
           "mean": (cal.get("after") or {}).get("mean"),
           "max": (cal.get("after") or {}).get("max"), "sigma": data.get("sigma")}
    if isinstance(val, dict) and val.get("after"):
        out["validation_rms"] = val["after"].get("rms")
    return out


def _check_arm(source: ModelSource, data: dict, where: Path) -> None:
    """The result's values must fit the model (same parameters and nominal values)."""
    from kinecal.io.result_values import model_for_data, parameters_from_data

    model = load_stored_model(source)
    parameters_from_data(model_for_data(model, data, where), data, where)


def calibration_row(serial: str, data: dict, where: str | Path, *,
                    source: ModelSource | None, report: Path | None = None,
                    inputs: list[dict] | None = None, date: datetime | None = None,
                    operator: str | None = None, instrument: str | None = None,
                    note: str | None = None, command: str | None = None,
                    force_reason: str | None = None) -> dict[str, Any]:
    """The ``events`` row of a calibration (module docstring); `where`: its result file
    (for messages and the inputs)."""
    from kinecal import __version__
    from kinecal.registry.store import dumps

    where = Path(where)
    subject = result_subject(data, where)
    document = dumps(data)
    digest = sha256_bytes(document.encode("utf-8"))
    recorded = format_date(now())
    row: dict[str, Any] = {
        "kind": "calibration", "subject": subject, "date": format_date(date or now()),
        "recorded": recorded, "kinecal": __version__, "operator": operator,
        "instrument": instrument, "note": note, "command": command,
        "inputs": json.dumps(inputs or [], sort_keys=True),
        "document": document, "document_sha256": digest,
    }
    row["at"] = datetime.fromisoformat(row["date"]).timestamp()
    if subject == "arm":
        if source is None:
            raise InputError("a serial arm's calibration needs its model", option="--model")
        _check_arm(source, data, where)
        row.update(model_name=source.name, model_file=source.file, model_text=source.text,
                   model_sha256=source.sha256, base_link=source.base_link,
                   tip_link=source.tip_link)
        summary = _arm_summary(data)
    else:
        summary = {"setup": data.get("setup"), "length_unit": data.get("length_unit")}
    row["summary"] = json.dumps(summary, sort_keys=True, allow_nan=False, default=str)
    if report is not None:
        size = report.stat().st_size
        if size > MAX_REPORT_BYTES:
            raise InputError(f"a report of {size} bytes: the registry keeps at most "
                             f"{MAX_REPORT_BYTES}", option="--report")
        blob = report.read_bytes()
        row.update(report=blob, report_name=report.name, report_sha256=sha256_bytes(blob))
    key = ["calibration", serial, digest]
    if force_reason is not None:  # once more, on purpose: a key of its own
        key += [recorded, force_reason, str(now().timestamp())]
    row["uid"] = sha256_bytes("\x00".join(key).encode("utf-8"))
    return row


def check_row(serial: str, calibration_id: int, result: dict, *, inputs: list[dict],
              date: datetime | None = None, operator: str | None = None,
              instrument: str | None = None, note: str | None = None,
              command: str | None = None, uid: str | None = None) -> dict[str, Any]:
    """The ``events`` row of a check (`kinecal.registry.check.CheckResult.to_dict`). Its
    key: the serial, the calibration judged, the inputs' SHA-256 and the date (the same
    check recorded twice, by a retried task, is one record)."""
    from kinecal import __version__
    from kinecal.registry.store import dumps

    when = format_date(date or now())
    document = dumps(result)
    summary = {"poses": len(result.get("poses") or []), "dof": result.get("dof"),
               "directions": result.get("directions") or {},
               "register_base": result.get("register_base"),
               "length_unit": result.get("length_unit")}
    key = uid or sha256_bytes("\x00".join(
        ["check", serial, str(calibration_id), when,
         *sorted(f"{e['name']}={e['sha256']}" for e in inputs)]).encode("utf-8"))
    return {
        "uid": key, "kind": "check", "subject": "arm", "date": when,
        "at": datetime.fromisoformat(when).timestamp(), "recorded": format_date(now()),
        "kinecal": __version__, "operator": operator, "instrument": instrument, "note": note,
        "command": command, "inputs": json.dumps(inputs, sort_keys=True),
        "calibration_id": calibration_id, "verdict": result["verdict"],
        "statistic": result["statistic"], "p_value": result["p_value"],
        "limit_value": result["limit"], "deviation": result["deviation"],
        "summary": json.dumps(summary, sort_keys=True, allow_nan=False),
        "document": document, "document_sha256": sha256_bytes(document.encode("utf-8")),
    }
