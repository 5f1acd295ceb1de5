"""ISO 9283 tables, figure and report (``kinecal iso9283 --report``), and the ISO 9283
section of a calibration report whose validation poses were measured in repeated cycles.

The figures are those of `kinecal.metrology.iso9283`; this module only lays them out.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any

import numpy as np

from kinecal.data import RepeatedPoses
from kinecal.metrology.iso9283 import STANDARD_CYCLES, Iso9283Result, iso9283
from kinecal.report.document import write_report
from kinecal.report.figures import figure_png, new_figure
from kinecal.report.markup import image_tag, kv, page, section, table
from kinecal.report.provenance import Provenance, collect, provenance_section
from kinecal.report.summary import summary_block
from kinecal.report.warnings import warnings_section

__all__ = ["iso9283_report", "iso9283_sections", "plot_iso9283", "repeated_validation",
           "validation_iso9283_section"]

_BEFORE, _AFTER, _RP = "#b0b0b0", "#1f77b4", "#ff7f0e"


def plot_iso9283(res: Iso9283Result, before: Iso9283Result | None = None) -> Any:
    """Two panels: AP and RP per pose (AP before in grey when `before` is given), and the
    distance l_j of every cycle from its pose's barycentre against the cycle number (drift
    and warm-up show as trends). Returns the Figure."""
    d = res.data
    fig, (a1, a2) = new_figure(1, 2)
    idx = np.arange(len(d.labels))
    if before is not None:
        a1.bar(idx - 0.27, before.poses["AP"], width=0.27, color=_BEFORE, label="AP before")
        a1.bar(idx, res.poses["AP"], width=0.27, color=_AFTER, label="AP after")
        a1.bar(idx + 0.27, res.poses["RP"], width=0.27, color=_RP, label="RP")
    else:
        a1.bar(idx - 0.2, res.poses["AP"], width=0.4, color=_AFTER, label="AP")
        a1.bar(idx + 0.2, res.poses["RP"], width=0.4, color=_RP, label="RP")
    a1.set_xticks(idx, [str(s) for s in d.labels], rotation=45 if len(idx) > 8 else 0)
    top = float(max(np.max(res.poses["AP"]), np.max(res.poses["RP"]),
                    0.0 if before is None else np.max(before.poses["AP"])))
    a1.set_ylim(0.0, 1.3 * top if top > 0 else 1.0)  # room for the legend
    a1.set_ylabel(f"[{d.length_unit}]")
    a1.set_title("Pose accuracy AP and repeatability RP")
    a1.legend(fontsize="small", ncol=3, loc="upper center")
    m = np.asarray(d.measured, float)
    lj = np.linalg.norm(m - m.mean(axis=1, keepdims=True), axis=2)
    for i, label in enumerate(d.labels):
        a2.plot(d.cycles, lj[i], marker=".", linewidth=1, label=str(label))
    a2.set_xlabel("cycle")
    a2.set_ylabel(f"l_j, distance to barycentre [{d.length_unit}]")
    a2.set_title("Scatter per cycle")
    if len(d.labels) <= 10:
        a2.legend(fontsize="x-small", ncol=2)
    return fig


def _pose_table(res: Iso9283Result, before: Iso9283Result | None) -> str:
    u = res.data.length_unit
    p = res.poses
    head = ["pose", *([f"AP before [{u}]"] if before is not None else []), f"AP [{u}]",
            f"APx [{u}]", f"APy [{u}]", f"APz [{u}]", f"RP [{u}]", f"l̄ [{u}]", f"S_l [{u}]"]
    rows = [(label, *([float(before.poses["AP"][i])] if before is not None else []),
             *(float(p[k][i]) for k in ("AP", "APx", "APy", "APz", "RP", "l_mean", "S_l")))
            for i, label in enumerate(res.data.labels)]
    return table(head, rows, digits=5)


def _orientation_table(res: Iso9283Result) -> str:
    keys = [k for k in ("APa", "APb", "APc", "RPa", "RPb", "RPc") if k in res.poses]
    if not keys:
        return ""
    rows = [(label, *(math.degrees(float(res.poses[k][i])) for k in keys))
            for i, label in enumerate(res.data.labels)]
    note = ("<p>Orientation (a, b, c: rotations about the x, y, z axes, R = Rz(c) Ry(b) "
            "Rx(a)), in degrees" + ("" if "APa" in keys else "; no commanded orientation, so "
                                    "repeatability only") + ".</p>")
    return note + table(["pose", *(f"{k} [deg]" for k in keys)], rows, digits=5)


def _distance_table(res: Iso9283Result) -> str:
    if not res.distances:
        return "<p>One pose: no distance figures.</p>"
    u = res.data.length_unit
    keys = ["D_commanded", "D_mean", "AD", "ADx", "ADy", "ADz", "RD", "RDx", "RDy", "RDz"]
    labels = res.data.labels
    rows = [(f"{labels[i]} - {labels[k]}", *(fig[key] for key in keys))
            for (i, k), fig in zip(res.pairs, res.distances, strict=True)]
    out = table(["poses", f"D_c [{u}]", f"D̄ [{u}]", *(f"{k} [{u}]" for k in keys[2:])], rows,
                digits=5)
    okeys = [k for k in ("ADa", "ADb", "ADc", "RDa", "RDb", "RDc") if k in res.distances[0]]
    if okeys:
        rows = [(f"{labels[i]} - {labels[k]}", *(math.degrees(fig[key]) for key in okeys))
                for (i, k), fig in zip(res.pairs, res.distances, strict=True)]
        out += table(["poses", *(f"{k} [deg]" for k in okeys)], rows, digits=5)
    return out


def iso9283_sections(res: Iso9283Result, before: Iso9283Result | None = None) -> list[str]:
    """The report sections: per-pose position and orientation figures, distances, figure."""
    n = res.data.n_cycles
    short = (f"<p>{n} cycles; ISO 9283 prescribes {STANDARD_CYCLES}: with fewer, RP and RD "
             "are less certain.</p>" if n < STANDARD_CYCLES else "")
    poses = (short + _pose_table(res, before) + _orientation_table(res)
             + "<p>AP: distance from the commanded position to the barycentre of the cycles "
             "(clause 7.2.1); RP = l̄ + 3 S_l (clause 7.2.2), l_j the distance of cycle j from "
             "the barycentre.</p>")
    dist = (_distance_table(res) + "<p>AD = D̄ - D_c, RD = 3 S_D (clause 7.3): D_j the "
            "distance between the two poses measured in cycle j, D_c the commanded one; the "
            "x, y, z (and a, b, c) columns use the absolute component differences.</p>")
    fig = image_tag(figure_png(plot_iso9283(res, before)), "ISO 9283 figure",
                    "Left: AP and RP per pose. Right: distance of each cycle from its pose's "
                    "barycentre.", "fig-iso9283")
    return [section("iso-poses", "Pose accuracy and repeatability (ISO 9283, 7.2)", poses),
            section("iso-distances", "Distance accuracy and repeatability (ISO 9283, 7.3)",
                    dist),
            section("figures", "Figure", fig)]


def iso9283_report(res: Iso9283Result, path: str | Path, before: Iso9283Result | None = None,
                   provenance: Provenance | None = None,
                   warnings: list[Any] | None = None) -> Path:
    """Write the ISO 9283 report (HTML, or PDF for ``.pdf``) of a test; returns `path`.

    `before`: the same test against another commanded pose (the nominal model, when
    `res` uses the calibrated one), shown beside AP.
    """
    d = res.data
    provenance = collect() if provenance is None else provenance
    ap, rp = res.poses["AP"], res.poses["RP"]
    worst = int(np.argmax(ap))
    lines = [f"<strong>{len(d.labels)} poses, {d.n_cycles} cycles</strong>: AP "
             f"{ap.min():.4g} to <strong>{ap.max():.4g} {html.escape(d.length_unit)}</strong> "
             f"(largest at pose {html.escape(str(d.labels[worst]))}); RP {rp.min():.4g} to "
             f"<strong>{rp.max():.4g} {html.escape(d.length_unit)}</strong>."]
    if before is not None:
        lines.append(f"AP with the nominal model: {before.poses['AP'].min():.4g} to "
                     f"{before.poses['AP'].max():.4g} {html.escape(d.length_unit)} (mean "
                     f"{before.poses['AP'].mean():.4g} &rarr; <strong>{ap.mean():.4g}"
                     "</strong>).")
    if res.distances:
        ad = np.array([abs(f["AD"]) for f in res.distances])
        lines.append(f"Distance accuracy |AD| up to {ad.max():.4g}, RD up to "
                     f"{max(f['RD'] for f in res.distances):.4g} "
                     f"{html.escape(d.length_unit)} over {len(ad)} pose pair(s).")
    info = kv([("data", d.source or "-"), ("poses", len(d.labels)), ("cycles", d.n_cycles),
               ("cycle numbers", f"{int(d.cycles[0])} to {int(d.cycles[-1])}"),
               ("length unit", d.length_unit),
               ("commanded pose", "forward kinematics of the joints" if d.joints is not None
                else "cx, cy, cz columns"),
               ("orientation", "measured" if d.measured_rotations is not None else "not measured")])
    sections = [summary_block(lines), warnings_section(warnings),
                provenance_section(provenance), section("summary", "Test", info),
                *iso9283_sections(res, before)]
    doc = page("ISO 9283 pose and distance characteristics",
               f"{len(d.labels)} poses x {d.n_cycles} cycles", sections, provenance.created)
    return write_report(path, doc)


# ------------------------------------------------------------ calibration validation
def repeated_validation(q: Any, xyz: Any, model: Any, params: Any = None,
                        tol: float = 1e-9) -> RepeatedPoses | None:
    """Validation rows as an ISO 9283 test: rows with equal joint values (within `tol`,
    rad) are the cycles of one pose, cycle j its j-th row; the commanded pose is the
    model's forward kinematics (with `params`). None unless at least one pose is repeated
    and every pose has the same number (>= 2) of rows."""
    q, xyz = np.asarray(q, float), np.asarray(xyz, float)
    groups: list[list[int]] = []
    for r in range(len(q)):
        for g in groups:
            if np.all(np.abs(q[g[0]] - q[r]) <= tol):
                g.append(r)
                break
        else:
            groups.append([r])
        if len(groups) > 1000:
            return None
    counts = {len(g) for g in groups}
    if len(counts) != 1 or counts.pop() < 2:
        return None
    idx = np.asarray(groups)
    commanded = model.positions(q[idx[:, 0]], params)
    return RepeatedPoses(tuple(str(k + 1) for k in range(len(groups))),
                         np.arange(1, idx.shape[1] + 1), xyz[idx], commanded,
                         length_unit=model.length_unit, source="validation poses")


def validation_iso9283_section(result: Any, validation: Any = None) -> str:
    """ISO 9283 AP (before and after) and RP of the validation poses of a calibration, when
    `validation` (the validation `Measurements`) repeats poses (`repeated_validation`);
    else the empty string."""
    if validation is None or getattr(validation, "marker", None) is not None:
        return ""  # several markers share joint values: equal joints are not one pose
    after = repeated_validation(validation.q, validation.xyz, result.model)
    if after is None:
        return ""
    before = iso9283(repeated_validation(validation.q, validation.xyz, result.nominal_model))
    res = iso9283(after)
    body = ("<p>The validation rows repeat poses (equal joint values): each pose's rows are "
            "its cycles, the commanded position is the model's forward kinematics, before "
            "(nominal) and after (calibrated) calibration.</p>"
            + _pose_table(res, before))
    return section("iso9283", "ISO 9283 pose accuracy of the validation poses", body)
