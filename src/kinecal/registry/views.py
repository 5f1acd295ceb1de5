"""What ``registry show`` and ``registry history`` print: a robot's record and its history
as plain text, and the ``show --json`` view."""

from __future__ import annotations

from typing import Any

__all__ = ["history_text", "show_text", "show_view"]


def _num(v: Any, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}g}"


def show_view(reg: Any, serial: str) -> dict[str, Any]:
    """A robot's record: its current calibration(s), counts, last check, current changes
    and retractions."""
    hist = reg.history(serial)
    events = hist["events"]
    cals = [e for e in events if e["kind"] == "calibration"]
    checks = [e for e in events if e["kind"] == "check"]
    current = {}
    for subject, eid in hist["current"].items():
        ev = next(e for e in cals if e["id"] == eid)
        current[subject] = {k: ev.get(k) for k in ("id", "date", "model", "operator",
                                                    "instrument", "note", "summary",
                                                    "inputs", "report", "command")}
    return {"serial": serial, "calibrations": len(cals), "checks": len(checks),
            "current": current, "last_check": checks[-1] if checks else None,
            "current_changes": hist["current_changes"], "retracted": hist["retracted"]}


def show_text(view: dict[str, Any]) -> str:
    """`show_view` as text."""
    lines = [f"robot {view['serial']}: {view['calibrations']} calibration(s), "
             f"{view['checks']} check(s)"]
    for subject, cur in view["current"].items():
        s = cur["summary"] or {}
        what = "current calibration" if subject == "arm" else f"current {subject} calibration"
        extra = (f", {s.get('method')}, {s.get('n')} poses, RMS after "
                 f"{_num(s.get('rms'))} {s.get('length_unit', '')}") if subject == "arm" else ""
        lines.append(f"{what}: {cur['id']} ({cur['date']}, {cur.get('model') or '-'}"
                     f"{extra})")
        for key in ("operator", "instrument", "note"):
            if cur.get(key):
                lines.append(f"  {key}: {cur[key]}")
        for entry in cur.get("inputs") or []:
            lines.append(f"  input {entry['name']}: {entry['path']} sha256 {entry['sha256']}")
        if cur.get("report"):
            lines.append(f"  report {cur['report']['name']} sha256 {cur['report']['sha256']}")
    last = view["last_check"]
    if last:
        lines.append(f"last check: {last['id']} ({last['date']}): {last['verdict']}, "
                     f"deviation {_num(last['deviation'])} (limit {_num(last['limit'])}), "
                     f"p = {_num(last['p_value'], 3)}")
    for r in view["retracted"]:
        lines.append(f"retracted: record {r['id']} ({r['date']}): {r['reason']}")
    return "\n".join(lines)


def history_text(hist: dict[str, Any], drift: dict[str, Any]) -> str:
    """A history and its drift as text: one line per record, then the drift."""
    lines = [f"history of {hist['serial']} ({len(hist['events'])} records)"]
    for ev in hist["events"]:
        if ev["kind"] == "calibration":
            s = ev.get("summary") or {}
            mark = " (current)" if ev.get("current") else ""
            detail = (f"{ev.get('model') or ev.get('subject')}, RMS after {_num(s.get('rms'))}"
                      if ev.get("subject") == "arm" else ev.get("subject"))
            lines.append(f"{ev['date']}  {ev['id']:>6}  calibration  {detail}{mark}")
        else:
            lines.append(f"{ev['date']}  {ev['id']:>6}  check        {ev['verdict']:12s} "
                         f"deviation {_num(ev['deviation'])} (limit {_num(ev['limit'])}), "
                         f"p = {_num(ev['p_value'], 3)}")
        if ev.get("retracted"):
            lines.append(f"{'':27s}retracted: {ev['retracted']['reason']}")
    dev = drift["deviation"]
    if drift["calibration"] is not None and dev["checks"]:
        lines.append(f"since calibration {drift['calibration']} ({drift['since']}): "
                     f"{dev['checks']} check(s)")
        if dev["rate_per_year"] is not None:
            spread = "" if dev["rate_std"] is None else f" +- {_num(dev['rate_std'])}"
            lines.append(f"  systematic error grows {_num(dev['rate_per_year'])}{spread} "
                         f"per year{'' if dev['growing'] else ' (no significant growth)'}")
        if dev["crossed"]:
            lines.append(f"  the limit was crossed on {dev['crossed']}")
        elif dev["projected_crossing"]:
            lines.append(f"  projected to cross the limit {_num(drift['limit'])} on "
                         f"{dev['projected_crossing']}")
        for name, d in list(drift["directions"].items())[:6]:
            flag = "" if d["significant"] else " (not significant)"
            lines.append(f"  {name:12s} {d['rate_per_year']:+.4g} +- {d['rate_std']:.2g} "
                         f"{d['unit']}{flag}")
    return "\n".join(lines)
