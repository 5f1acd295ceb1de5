"""`KindsCalibrationResult`: a `CalibrationResult` of several measurement kinds.

Everything of the tracker result (parameters, uncertainty, JSON, report, model file),
plus per measurement set: its kind, noise (stated or estimated), error statistics per
observation before and after, and its solved unknowns (``extra["kinds"]``); the motions
the mix does not see (``extra["not_seen"]``); validation sets of any kind.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kinecal.calibration.serial.frames import station_lines
from kinecal.calibration.serial.result import CalibrationResult
from kinecal.metrology.stats import error_stats

__all__ = ["KindsCalibrationResult", "kind_entry", "kind_lines", "tip_lines"]


def kind_entry(block, sigma: np.ndarray | None, how: str, before: np.ndarray,
               after: np.ndarray, nuisance: list[dict] | None = None) -> dict[str, Any]:
    """One measurement set's entry of ``extra["kinds"]`` (JSON-able).

    `sigma`: its noise per observation (None: not known); `how`: ``stated``,
    ``estimated`` or ``not estimable``; `before` / `after`: error per observation
    (block unit).
    """
    entry: dict[str, Any] = {
        "file": block.source, "kind": block.kind, "unit": block.unit,
        "observations": int(block.n_obs), "rows": int(block.n_rows),
        "sigma": None if sigma is None else float(np.sqrt(np.mean(np.square(sigma)))),
        "sigma_source": how, "noise_of": block.noise_of,
        "before": error_stats(before), "after": error_stats(after),
    }
    if nuisance:
        entry["unknowns"] = nuisance
    return entry


def kind_lines(entries: list[dict], length_unit: str, title: str,
               factor: float = 1.0) -> list[str]:
    """Text table of per-kind statistics (summary, report): lengths times `factor` (from the
    model's unit to `length_unit`, the unit shown)."""
    if not entries:
        return []
    lines = ["", title,
             f"{'kind':8s} {'file':18s} {'n':>5s} {'sigma':>10s} {'rms before':>11s} "
             f"{'rms after':>10s} {'max after':>10s}"]
    for e in entries:
        length = e["unit"] == "length"
        unit, f = (length_unit, factor) if length else (e["unit"], 1.0)
        s = e["sigma"]
        sig = "-" if s is None else f"{s * f:.3g}{'*' if e['sigma_source'] == 'estimated' else ''}"
        name = str(e["file"]).replace("\\", "/").rsplit("/", 1)[-1][:18]
        lines.append(f"{e['kind']:8s} {name:18s} {e['observations']:5d} {sig:>10s} "
                     f"{e['before']['rms'] * f:11.4g} {e['after']['rms'] * f:10.4g} "
                     f"{e['after']['max'] * f:10.4g}" + ("" if length else f" {unit}"))
    if any(e["sigma_source"] == "estimated" for e in entries):
        lines.append(f"(* noise estimated from the fit: no --sigma or sigma column; "
                     f"{length_unit})")
    return lines


def tip_lines(tips: dict | None, length_unit: str, factor: float = 1.0) -> list[str]:
    """Text table of a robot system's errors per tip (rms and max before / after)."""
    if not tips:
        return []
    lines = ["", f"per tip (error per observation, {length_unit})",
             f"{'tip':24s} {'set':5s} {'n':>5s} {'rms before':>11s} {'rms after':>10s} "
             f"{'max after':>10s}"]
    for which, table in tips.items():
        for tip, e in table.items():
            if not e["n"]:
                continue
            lines.append(f"{tip[:24]:24s} {which[:5]:5s} {e['n']:5d} "
                         f"{e['before']['rms'] * factor:11.4g} {e['after']['rms'] * factor:10.4g} "
                         f"{e['after']['max'] * factor:10.4g}")
    return lines


@dataclass(repr=False)
class KindsCalibrationResult(CalibrationResult):
    """Outcome of a calibration from several measurement kinds (module docstring).

    ``errors_before`` / ``errors_after`` hold the error of every observation (a distance
    error, a touch's distance from its point or plane, a tracker point's distance error;
    length unit), file after file; ``q_calibration`` every configuration the files
    measured (for the predicted uncertainty).
    """

    def to_dict(self) -> dict[str, Any]:
        """The calibration JSON; a robot system's errors per tip go into the calibration
        and validation sections as ``by_tip[TIP].before|after.{mean, rms, max, ...}``."""
        out = super().to_dict()
        tips = out.pop("by_tip", None)
        if tips:
            out["calibration"]["by_tip"] = tips["calibration"]
            if out.get("validation") is not None and "validation" in tips:
                out["validation"]["by_tip"] = tips["validation"]
        return out

    def summary(self, unit: str | None = None) -> str:
        """The tracker summary with the per-kind table and the motions not seen; `unit`
        as `CalibrationResult.summary` (lengths of the text only)."""
        shown = self.display_unit(unit)
        unit, f = shown.name, shown.factor
        text = super().summary(unit).split("\n")
        extra = kind_lines(self.extra.get("kinds", []), unit,
                           f"per measurement set (rms, max: error per observation, {unit})", f)
        extra += kind_lines(self.extra.get("validation_kinds", []), unit,
                            "validation sets (their own unknowns fitted)", f)
        extra += station_lines(self.nominal_model, self.extra, unit, f)
        extra += tip_lines(self.extra.get("by_tip"), unit, f)
        if self.extra.get("system"):
            from kinecal.calibration.blocks.system_ident import system_lines

            extra += system_lines(self.extra["system"])
        unseen = self.extra.get("not_seen_words")
        if unseen:
            extra += ["", f"not seen by this mix of measurements: {unseen}; the parameters "
                      "that only move those are held at nominal"]
        if self.extra.get("fixtures_show"):
            from kinecal.calibration.blocks.motions import fixture_words

            extra += [f"known fixtures make visible: {fixture_words(self.extra['fixtures_show'])}"]
        # after the identifiability lines, before the error tables
        cut = next((i for i, line in enumerate(text) if not line), len(text))
        text = text[:cut] + extra + text[cut:]
        return "\n".join(line.replace("position error [", "error per observation [")
                         for line in text)
