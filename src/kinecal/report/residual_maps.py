"""Residual maps of an error-model calibration, and its report section.

Where a geometric calibration leaves error, the error has a shape: gravity sag grows with
the arm's horizontal reach, transmission errors repeat with a joint's angle. These maps
plot the calibration poses' distance errors against the reach and against every joint
angle:

* first row: after the geometric calibration (grey) and after the chosen error model
  (blue);
* one row per term family of the chosen model (compliance, harmonic, scale): the chosen
  model without that family, its other parameters refitted (grey), and the chosen model
  (blue), so the gap is what only that family explains, and where.

Reach is the tool point's distance from the robot base's vertical axis (perpendicular to
gravity), computed with the calibrated geometry. `ResidualMaps.from_result` needs the
geometric calibration and the measured positions, which the result of
`kinecal.calibration.serial.error_model.calibrate_error_model` (an `ErrorModelResult`) keeps.
"""

from __future__ import annotations

import base64
import dataclasses
import html
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.frames import frame_transform

__all__ = ["ResidualMaps", "error_model_section", "plot_residual_maps"]

Array = NDArray[np.float64]
#: pixels per inch of the maps (their size follows the number of rows and joints)
_DPI = 100
_BEFORE = "#9a9a9a"
_AFTER = "#1f77b4"


@dataclasses.dataclass(frozen=True)
class ResidualMaps:
    """Distance errors of the calibration poses under several models.

    Attributes
    ----------
    q : ndarray, shape (N, n_joints)
        Joint readings (rad; prismatic joints in the length unit).
    reach : ndarray, shape (N,)
        Horizontal reach of the tool point (length unit).
    rows : list of (str, ndarray (N,), str, ndarray (N,))
        Per row: label and errors of the grey series, label and errors of the blue one.
    unit : str
        Length unit.
    revolute : ndarray of bool, shape (n_joints,)
        Revolute joints (their angles are plotted in degrees).
    """

    q: Array
    reach: Array
    rows: list
    unit: str
    revolute: NDArray[np.bool_]

    @classmethod
    def from_result(cls, result: Any, geometric: Any, xyz: Array) -> ResidualMaps:
        """Maps of an error-model `result` with its `geometric` calibration and the measured
        positions `xyz` ``(N, 3)`` of the calibration poses."""
        model = result.nominal_model
        q = np.asarray(result.q_calibration, dtype=float)
        p = np.asarray(result.params, dtype=float)
        xyz = np.asarray(xyz, dtype=float)

        marker = getattr(result, "marker_calibration", None)  # several markers: per pose

        def errors(params: Array, m: Any = model) -> Array:
            return np.linalg.norm(m.positions(q, params, marker) - xyz, axis=1)

        rows = [("geometric calibration", errors(geometric.params, geometric.nominal_model),
                 "error model", errors(p))]
        terms = model._joint_terms
        n_geo = model._n_geometric
        if terms is not None:
            # without a family: its coefficients at nominal, the other free parameters
            # refitted (one Gauss-Newton step from the solution, evaluated exactly)
            free = model.index(list(result.free))
            J = model.jacobian_t(q, p, columns=free, marker=marker).transpose(2, 1, 0)
            J = J.reshape(-1, free.size)
            r = (model.positions(q, p, marker) - xyz).ravel()
            nominal = model.nominal
            for family in dict.fromkeys(terms.families):
                drop = np.array([k >= n_geo and terms.families[k - n_geo] == family
                                 for k in free])
                if not drop.any():
                    continue
                p_f = p.copy()
                p_f[free[drop]] = nominal[free[drop]]
                r_f = r + J[:, drop] @ (nominal[free[drop]] - p[free[drop]])
                p_f[free[~drop]] -= np.linalg.lstsq(J[:, ~drop], r_f, rcond=None)[0]
                rows.append((f"without {family} (refitted)", errors(p_f), "with " + family,
                             rows[0][3]))
        # reach in the robot base frame, perpendicular to gravity
        B = frame_transform(model, p, "base")
        P = (model.positions(q, p, marker) - B[:3, 3]) @ B[:3, :3]
        g = np.asarray(model.joint_errors.gravity if model.joint_errors is not None
                       else (0.0, 0.0, -1.0))
        reach = np.linalg.norm(P - np.outer(P @ g, g), axis=1)
        return cls(q, reach, rows, model.length_unit, ~model.is_prismatic())


def _binned(ax: Any, x: Array, y: Array, color: str) -> None:
    """Scatter of (x, y) with the mean of y in 12 bins of x as a line."""
    ax.scatter(x, y, s=3, color=color, alpha=0.35, linewidths=0)
    edges = np.linspace(x.min(), x.max(), 13)
    if edges[-1] <= edges[0]:
        return
    idx = np.clip(np.digitize(x, edges) - 1, 0, 11)
    counts = np.bincount(idx, minlength=12)
    sums = np.bincount(idx, weights=y, minlength=12)
    ok = counts > 0
    mid = 0.5 * (edges[:-1] + edges[1:])
    ax.plot(mid[ok], sums[ok] / counts[ok], color=color, linewidth=1.6)


def plot_residual_maps(maps: ResidualMaps) -> Any:
    """The maps as one matplotlib figure: a row per comparison, columns reach and joints."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    n_j = maps.q.shape[1]
    nrows, ncols = len(maps.rows), 1 + n_j
    fig = Figure(figsize=(1.9 * ncols, 1.75 * nrows + 0.3), dpi=_DPI)
    FigureCanvasAgg(fig)
    axes = np.atleast_2d(fig.subplots(nrows, ncols, sharey="row", squeeze=False))
    for r, (grey_label, grey, blue_label, blue) in enumerate(maps.rows):
        xs = [maps.reach] + [np.degrees(maps.q[:, j]) if maps.revolute[j] else maps.q[:, j]
                             for j in range(n_j)]
        for c, x in enumerate(xs):
            ax = axes[r, c]
            _binned(ax, x, grey, _BEFORE)
            _binned(ax, x, blue, _AFTER)
            ax.tick_params(labelsize=7)
            if r == nrows - 1:
                ax.set_xlabel(f"reach [{maps.unit}]" if c == 0 else
                              f"q{c} [{'deg' if maps.revolute[c - 1] else maps.unit}]",
                              fontsize=8)
        axes[r, 0].set_ylabel(f"error [{maps.unit}]", fontsize=8)
        axes[r, 0].set_title(f"grey: {grey_label}; blue: {blue_label}", fontsize=8,
                             loc="left")
    fig.tight_layout()
    return fig


def _png_tag(fig: Any, alt: str, caption: str, ident: str = "fig-residual-maps") -> str:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_DPI)
    w, h = (round(v * _DPI) for v in fig.get_size_inches())
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return (f'<figure id="{ident}"><img class="fig" src="data:image/png;base64,'
            f'{data}" alt="{html.escape(alt)}" width="{w}" height="{h}">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def error_model_section(result: Any) -> list[str]:
    """The report sections of an error-model calibration ([] for a plain one): the choice
    (cross-validation table), the coefficients' identifiability, the residual maps."""
    from kinecal.report.markup import fmt, section, table

    info = result.extra.get("error_model") if isinstance(result.extra, dict) else None
    if not info:
        return []
    unit = result.nominal_model.length_unit
    body = (f"<p>Requested <code>{html.escape(str(info['requested']))}</code>; model used: "
            f"<strong>{html.escape(str(info['selected']))}</strong>.</p>")
    if info.get("candidates"):
        def beyond(r):
            v = [x for x in (r.get("cv_blocked") or {}).values() if x is not None]
            return sum(v) / len(v) if v else None

        rows = [(r["model"], r["parameters"], r.get("score"), r["cv_mean"], beyond(r),
                 r["cv_se"], ("chosen" if r["chosen"] else "") + (" best" if r["best"] else ""))
                for r in info["candidates"]]
        body += (f"<p>{int(info['folds'])}-fold cross-validation on the calibration poses only "
                 "(deterministic folds): random folds score how a model does among the "
                 "calibration poses (within), folds blocked by each joint's range (and by "
                 "time, for time-ordered poses) how it does beyond them; the score is their "
                 "average. The one-standard-error rule takes the candidate with the fewest "
                 "parameters whose score is within one standard error of the best. The "
                 "validation poses are never seen by the choice.</p>"
                 + table(["candidate", "parameters", f"score [{unit}]", f"within [{unit}]",
                          f"beyond [{unit}]", f"standard error [{unit}]", ""], rows,
                         digits=5))
    geo = info.get("geometric") or {}
    after = result.validation_stats or result.calibration_stats
    where = "validation" if result.validation_stats else "calibration"
    ref = geo.get(f"{where}_mean")
    if ref is not None:
        body += (f"<p>Mean error on the {where} poses: geometric calibration "
                 f"{fmt(float(ref))} {unit}, {html.escape(str(info['selected']))} "
                 f"{fmt(after['after']['mean'])} {unit}.</p>")
    terms = result.extra.get("joint_errors") or {}
    if terms.get("unidentifiable"):
        confounded = [(n, ", ".join(f"{c:+.3g} {o}" for o, c in sorted(
            terms["confounded_with"].get(n, {}).items(), key=lambda kv: -abs(kv[1]))[:4])
            or "no effect on these poses") for n in terms["unidentifiable"]]
        body += ("<p>Joint-error coefficients held at nominal: their effect on these poses "
                 "equals a combination of free parameters (coefficients per unit of each "
                 "parameter: length unit, rad).</p>"
                 + table(["coefficient", "same effect as"], confounded, left=2))
    if terms.get("correlated_with"):
        corr = [(n, ", ".join(f"{o} {c:+.2f}" for o, c in list(d.items())[:4]))
                for n, d in terms["correlated_with"].items()]
        body += ("<p>Identifiable, but strongly correlated (|r| &ge; 0.9) with other free "
                 "parameters: their values trade off, their standard errors are larger.</p>"
                 + table(["coefficient", "correlation with"], corr, left=2))
    out = [section("error-model", "Error model", body)]
    geometric = getattr(result, "geometric", None)
    xyz = getattr(result, "measured_xyz", None)
    if (geometric is not None and xyz is not None and result.q_calibration is not None
            and result.nominal_model.joint_errors is not None):
        fig = plot_residual_maps(ResidualMaps.from_result(result, geometric, xyz))
        caption = ("Distance error of the calibration poses against the tool's horizontal "
                   "reach and each joint angle (dots: poses; lines: means in 12 bins). Top: "
                   "geometric calibration vs the error model; below, per term family: the "
                   "model without that family (other parameters refitted) vs with it.")
        out.append(section("residual-maps", "Residual maps",
                           _png_tag(fig, "residual maps", caption)))
    return out
