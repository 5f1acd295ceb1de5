"""HTML report of a hand-eye calibration from images (``kinecal handeye-images --report``).

Self-contained like the other reports (`kinecal.report.html`): the solution X with its
standard deviations and units, the board pose, the camera, the per-image reprojection
errors (figure and table, outliers and rejected images marked with their reasons), and a
thumbnail of every image with the detected corners (green) and the corners predicted by
the solution (red crosses).
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kinecal.report.document import write_report
from kinecal.report.figures import figure_png, new_figure
from kinecal.report.markup import image_tag, page, section, table
from kinecal.report.provenance import Provenance, collect, provenance_section, time_rows
from kinecal.report.summary import COVERAGE_K

__all__ = ["handeye_images_report", "plot_image_errors", "thumbnail_jpeg"]

_THUMB_CSS = ("<style>.thumbs{display:flex;flex-wrap:wrap;gap:.6em}.thumbs figure{margin:0;"
              "width:15em}.thumbs img{width:15em;height:auto;border:2px solid #9c9}"
              ".thumbs figure.rejected img{border-color:#d66}.thumbs figure.outlier img"
              "{border-color:#e90}.thumbs figcaption{font-size:.8em}</style>")


def plot_image_errors(result: Any) -> Any:
    """Bar figure: reprojection RMS per image (px); outliers orange, rejected marked x."""
    fig, ax = new_figure()
    recs = result.records
    idx = np.arange(len(recs))
    rms = np.array([r.rms_px if r.rms_px is not None else np.nan for r in recs])
    colors = ["#e69500" if r.status == "outlier" else "#1f77b4" for r in recs]
    ax.bar(idx, np.nan_to_num(rms), color=colors, width=0.8)
    rej = [k for k, r in enumerate(recs) if r.status == "rejected"]
    if rej:
        top = np.nanmax(rms) if np.any(np.isfinite(rms)) else 1.0
        ax.plot(rej, np.full(len(rej), 0.05 * top), "x", color="#d62728", label="rejected")
        ax.legend(loc="upper right")
    ax.set_xlabel("image (input order)")
    ax.set_ylabel("reprojection RMS [px]")
    ax.set_title("Corner reprojection error per image after the refinement")
    ax.set_xlim(-0.6, len(recs) - 0.4)
    if len(recs) <= 40:
        ax.set_xticks(idx)
    return fig


def thumbnail_jpeg(gray: Any, observed: Any = None, predicted: Any = None,
                   width: int = 320) -> bytes:
    """JPEG bytes of an image scaled to `width` px with observed corners (green circles) and
    predicted corners (red crosses) drawn."""
    from kinecal.vision import require_cv2

    cv2 = require_cv2()
    img = np.asarray(gray)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    h, w = img.shape[:2]
    s = width / float(w)
    small = cv2.resize(img, (width, max(1, round(h * s))), interpolation=cv2.INTER_AREA)
    if observed is not None:
        for u, v in np.asarray(observed).reshape(-1, 2):
            cv2.circle(small, _pt(u, v, s), 3, (40, 200, 40), 1, cv2.LINE_AA)
    if predicted is not None:
        for u, v in np.asarray(predicted).reshape(-1, 2):
            cv2.drawMarker(small, _pt(u, v, s), (40, 40, 230), cv2.MARKER_CROSS, 5, 1, cv2.LINE_AA)
    ok, buf = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, 82])
    return buf.tobytes() if ok else b""


def _pt(u: float, v: float, s: float) -> tuple[int, int]:
    """Pixel of a full-size image point in the image scaled by `s` (pixel centres)."""
    return round(float((u + 0.5) * s - 0.5)), round(float((v + 0.5) * s - 0.5))


def _matrix_table(T: Any) -> str:
    return table(["", "c1", "c2", "c3", "t [mm]"],
                 [[f"r{i + 1}", *[float(v) for v in row]] for i, row in enumerate(T)], digits=7)


def handeye_images_report(result: Any, path: str | Path,
                          images: Sequence[Any] | None = None,
                          result_dict: dict[str, Any] | None = None,
                          provenance: Provenance | None = None) -> Path:
    """Write the report of an `ImageHandEyeResult` (HTML, or PDF for ``.pdf``) with its
    record (`provenance`: date and version when omitted); returns `path`.

    Parameters
    ----------
    result : ImageHandEyeResult
    path : str or Path
    images : sequence of ndarray or path, optional
        The input images (thumbnails are drawn when given).
    result_dict : dict, optional
        The JSON dict (its warnings are listed); default ``result.to_dict()``.
    """
    d = result_dict or result.to_dict()
    ref = result.refinement
    frame = d.get("X_frame", "X")
    tframe = d.get("target_frame", "target")
    xr, xt = result.X_std
    yr, yt = ref.Y_std
    intr = result.intrinsics
    summary = table(None, [
        ("setup", result.setup), ("board", result.board.spec),
        ("images", len(result.records)), ("used", len(result.used)),
        ("rejected", len(result.rejected)), ("outliers", len(result.outliers)),
        ("seed (closed form)", result.method + (" + robust pose LM" if result.seed.refine == "lm"
                                                else "")),
        ("reprojection RMS [px]", ref.rms_px), ("corner sigma [px]", ref.sigma_px),
        ("intrinsics", intr.source + (" (refined with X)" if result.intrinsics_refined else "")),
        ("intrinsics calibration RMS [px]", intr.rms_px),
        *time_rows(result.seconds),
    ])
    xsec = (_matrix_table(result.X)
            + "<p>Standard deviation (1 sigma, from the reprojection residuals): rotation "
            + html.escape(", ".join(f"{v:.4g}" for v in xr)) + " deg about X's x, y, z axes; "
            "translation " + html.escape(", ".join(f"{v:.4g}" for v in xt)) + " mm. Expanded "
            "(k = 2): rotation " + html.escape(", ".join(f"{COVERAGE_K * v:.4g}" for v in xr))
            + " deg; translation "
            + html.escape(", ".join(f"{COVERAGE_K * v:.4g}" for v in xt)) + " mm.</p>")
    ysec = (_matrix_table(result.target)
            + "<p>Standard deviation: rotation " + html.escape(", ".join(f"{v:.4g}" for v in yr))
            + " deg; translation " + html.escape(", ".join(f"{v:.4g}" for v in yt)) + " mm.</p>")
    K, dist = intr.K, intr.cv_dist
    names = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"]
    vals = [K[0, 0], K[1, 1], K[0, 2], K[1, 2], *dist]
    cam = table(["parameter", "value", "unit"],
                [(n, float(v), "px" if k < 4 else "-") for k, (n, v) in enumerate(zip(names, vals,
                                                                                    strict=False))],
                left=1, digits=7)
    fig = image_tag(figure_png(plot_image_errors(result)), "reprojection error per image",
                    "RMS distance between detected and predicted corners per image (orange: "
                    "outlier stations, x: rejected images).", "fig-images")
    rows, classes = [], []
    for r in result.records:
        e = r.to_dict()
        rows.append((r.name, r.status, e["corners"], e["rms_px"], e["max_px"], e["tilt_deg"],
                     e["edge_width_px"], r.reason or "-"))
        classes.append("fixed" if r.status != "used" else "")
    itab = table(["image", "status", "corners", "RMS [px]", "max [px]", "tilt [deg]",
                  "edge width [px]", "reason"], rows, left=2, row_classes=classes)
    provenance = collect() if provenance is None else provenance
    sections = [
        provenance_section(provenance),
        section("summary", "Set-up and solution", summary),
        section("transform", f"X ({frame})", xsec),
        section("target", f"Board pose ({tframe})", ysec),
        section("camera", "Camera", cam),
        section("figures", "Reprojection error per image", fig),
        section("images", "Images", itab),
    ]
    warns = d.get("warnings") or []
    if warns:
        sections.append(section("warnings", "Warnings", "<ul>" + "".join(
            f"<li>{html.escape(w['message'])} [{html.escape(w['code'])}]</li>" for w in warns)
            + "</ul>"))
    if images is not None:
        sections.append(section("thumbnails", "Detections", _thumbnails(result, images)))
    doc = page("Hand-eye calibration from images",
               f"{result.setup}, {len(result.used)} of {len(result.records)} images used",
               sections, provenance.created)
    doc = doc.replace("</head>", _THUMB_CSS + "</head>", 1)
    return write_report(path, doc)


def _thumbnails(result: Any, images: Sequence[Any]) -> str:
    from kinecal.vision.stages import load_gray

    parts = ["<p>Green circles: detected corners; red crosses: corners predicted by X, the "
             "board pose and the robot pose.</p><div class=\"thumbs\">"]
    for rec, im in zip(result.records, images, strict=True):
        gray = load_gray(im) if isinstance(im, str | Path) else np.asarray(im)
        if gray is None:
            cap = f"{rec.name}: {rec.status} - {rec.reason}"
            parts.append(f'<figure class="rejected"><figcaption>{html.escape(cap)}'
                         "</figcaption></figure>")
            continue
        det = rec.detection
        obs = None if det is None or not len(det.corners) else det.corners
        pred = obs - rec.residuals if rec.residuals is not None and obs is not None else None
        jpg = thumbnail_jpeg(gray, obs, pred)
        data = base64.b64encode(jpg).decode("ascii")
        rms = f", {rec.rms_px:.3f} px" if rec.rms_px is not None else ""
        cap = f"{rec.name}: {rec.status}{rms}" + (f" - {rec.reason}" if rec.reason else "")
        parts.append(f'<figure class="{html.escape(rec.status)}"><img src="data:image/jpeg;'
                     f'base64,{data}" alt="{html.escape(rec.name)}"><figcaption>'
                     f"{html.escape(cap)}</figcaption></figure>")
    parts.append("</div>")
    return "".join(parts)
