"""Report of an arm calibrated from camera images (``kinecal calibrate ... --images``), HTML
or PDF (``.pdf``): the record (date, inputs with their SHA-256, command line, operator,
instrument), the reprojection per station before (arm nominal, X and board refined) and
after, what the camera cannot identify in words, the parameter table with standard and
expanded (k = 2) uncertainties, X and the board pose."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from kinecal.errors import InputError
from kinecal.report.document import write_report
from kinecal.report.figures import _per_pose, figure_png, new_figure
from kinecal.report.markup import image_tag, kv, page, section, table
from kinecal.report.provenance import Provenance, collect, provenance_section
from kinecal.report.summary import COVERAGE_K
from kinecal.report.warnings import warnings_section

__all__ = ["arm_images_report"]


def _rms(v: Any) -> float:
    v = np.asarray(v, float)
    return float(np.sqrt(np.mean(v**2))) if v.size else float("nan")


def _matrix(T: Any) -> str:
    return table(None, [[float(v) for v in row] for row in np.asarray(T)], left=0)


def arm_images_report(result: Any, path: str | Path,
                      provenance: Provenance | None = None) -> Path:
    """Write the report of an `ArmCameraResult` (HTML, or PDF for a ``.pdf`` path) with its
    record (`provenance`: date and version when omitted); returns `path`."""
    path = Path(path)
    if path.is_dir():
        raise InputError("is a directory; expected a file path to write", file=path)
    nom = result.nominal_model
    keep = result.inliers
    fig, ax = new_figure()
    _per_pose(ax, result.before_px, result.after_px, "px",
              "Corner reprojection RMS per station: arm nominal (grey) and calibrated (blue)")
    ax.set_xlabel("station")
    ax.set_ylabel("reprojection RMS [px]")
    png = figure_png(fig)
    rep = result.identifiability.report
    summary = kv([
        ("model", nom.name), ("set-up", result.setup),
        ("stations", f"{len(result.station_names)} used, {len(result.outliers)} outlier(s), "
                     f"{len(result.extra.get('skipped', []))} skipped"),
        ("board", result.extra.get("board", "")),
        ("free arm parameters", f"{len(result.free)} (rank {rep.rank} of {len(rep.names)} "
                                "beside X and the board)"),
        ("reprojection RMS, arm nominal", f"{_rms(result.before_px[keep]):.4f} px"),
        ("reprojection RMS, calibrated", f"{_rms(result.after_px[keep]):.4f} px"),
        ("corner noise (1 sigma)", f"{result.sigma_px:.4f} px"),
    ])
    seen = "<ul>" + "".join(f"<li>{html.escape(s)}</li>"
                            for s in result.identifiability.sentences) + "</ul>"
    rows = [[n, e["nominal"], e["identified"], e["identified"] - e["nominal"],
             e["std"] if e["free"] else None, COVERAGE_K * e["std"] if e["free"] else None,
             "free" if e["free"] else "held"]
            for n, e in result.parameter_table().items()]
    params = table(["parameter", "nominal", "identified", "delta", "u (1 sigma)",
                    f"U (k = {COVERAGE_K:g})", ""], rows)
    xr, xt = result.X_std
    xstd = ("<p>Standard deviation (1 sigma): rotation "
            + html.escape(", ".join(f"{v:.4g}" for v in xr)) + " deg about X's axes, "
            "translation " + html.escape(", ".join(f"{v:.4g}" for v in xt))
            + f" {html.escape(nom.length_unit)}; expanded (k = {COVERAGE_K:g}): rotation "
            + html.escape(", ".join(f"{COVERAGE_K * v:.4g}" for v in xr)) + " deg, "
            "translation " + html.escape(", ".join(f"{COVERAGE_K * v:.4g}" for v in xt))
            + f" {html.escape(nom.length_unit)}.</p>")
    stations = table(["image", "status", "RMS before [px]", "RMS after [px]"],
                     [[n, "outlier" if i in result.outliers else "used", b, a]
                      for i, (n, b, a) in enumerate(zip(result.station_names, result.before_px,
                                                        result.after_px, strict=True))]
                     + [[s["image"], "skipped: " + s["reason"], None, None]
                        for s in result.extra.get("skipped", [])])
    frames = ("X (cam2flange)", "board pose (target2base)") if result.setup == "eye-in-hand" \
        else ("X (cam2base)", "board pose (target2flange)")
    provenance = collect() if provenance is None else provenance
    sections = [
        provenance_section(provenance),
        section("summary", "Summary", summary),
        section("not-seen", "What the camera cannot identify", seen),
        section("stations", "Reprojection per station",
                image_tag(png, "reprojection per station") + stations),
        section("parameters", f"Parameters ({nom.length_unit}, {nom.angle_unit})", params),
        section("mounts", "Camera mount and board pose",
                f"<h3>{frames[0]}</h3>" + _matrix(result.X) + xstd
                + f"<h3>{frames[1]}</h3>" + _matrix(result.board_pose)),
        warnings_section(result.warnings),
    ]
    doc = page(f"Calibration of {nom.name} from camera images",
               f"{result.setup}, {len(result.station_names)} stations", sections,
               provenance.created)
    return write_report(path, doc)
