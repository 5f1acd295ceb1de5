"""Plausibility checks of an arm calibration from images (stable codes, docs/diagnostics.md).

- ``reprojection-rms``: the calibrated arm still reprojects the corners to more than 2 px;
- ``outliers`` / ``many-outliers``: stations far outside the others' residual spread;
- ``board-scale``: the identified lengths are uniformly larger or smaller than nominal: the
  pixels take their scale from the board's size (`kinecal.calibration.camera.identify`), so
  a uniform misfit of the arm's lengths points at a wrong ``--board`` square size;
- ``initial-error``: the lengths changed beyond the tolerances *unevenly* (no board size
  explains them) and no outlier station does either: the images fit this model only as
  another arm (the stations of another robot, or the wrong model).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinecal import diagnostics

__all__ = ["BOARD_SCALE_LIMIT", "check_camera_fit", "length_scale", "uneven_lengths"]

#: relative uniform scale of the identified lengths beyond which ``board-scale`` is raised
#: (an arm's length errors of a few tenths of a millimetre average out to 0.01-0.05 %)
BOARD_SCALE_LIMIT = 0.003


def length_scale(res: Any) -> tuple[float, float]:
    """Least-squares factor ``s`` with identified ~ s * nominal over the free lengths longer
    than 5 % of the longest, and its standard error. ``(1, inf)`` without such lengths."""
    nom = res.nominal_model
    idx = nom.index(res.free)
    lengths = idx[~nom.is_angle()[idx]]
    v = nom.nominal[lengths]
    big = np.abs(v) > 0.05 * max(np.abs(v).max(initial=0.0), 1e-300)
    if not big.any():
        return 1.0, float("inf")
    v, w, sd = v[big], res.params[lengths][big], res.std[lengths][big]
    s = float(v @ w / (v @ v))
    se = float(np.sqrt(np.sum((v * np.where(np.isfinite(sd), sd, 0.0)) ** 2)) / (v @ v))
    return s, se


def uneven_lengths(res: Any, s: float) -> list[tuple[str, float]]:
    """The free lengths (name, change in the length unit) that the uniform scale `s` leaves
    beyond `TOLERANCE_MULTIPLE` tolerances plus three standard errors, largest first."""
    from kinecal.calibration.diagnostics.fit import TOLERANCE_MULTIPLE

    nom = res.nominal_model
    idx = nom.index(res.free)
    lengths = idx[~nom.is_angle()[idx]]
    if not lengths.size:
        return []
    left = res.params[lengths] - s * nom.nominal[lengths]
    sd = np.where(np.isfinite(res.std[lengths]), res.std[lengths], 0.0)
    bad = np.abs(left) > TOLERANCE_MULTIPLE * float(nom.tolerances["length"]) + 3.0 * sd
    order = np.argsort(-np.abs(left))
    return [(nom.parameter_names[lengths[k]], float(left[k])) for k in order if bad[k]]


def check_camera_fit(res: Any) -> None:
    """Issue the diagnostics of an `ArmCameraResult` (see the module docstring)."""
    keep = res.inliers
    after = float(np.sqrt(np.mean(res.after_px[keep] ** 2))) if keep.any() else 0.0
    if after > 2.0:
        kept = (" (or the outlier stations, kept by --loss linear, pull the fit: --loss huber "
                "leaves them out)" if res.outliers and res.loss == "linear" else "")
        diagnostics.warn("reprojection-rms",
                         f"the calibrated arm reprojects the corners to {after:.2f} px RMS: the "
                         "joints, their unit or order, the --setup, the board's square size "
                         f"(--board) or the intrinsics are probably wrong{kept}")
    n = len(res.station_names)
    if res.outliers:
        names = ", ".join(res.station_names[i] for i in res.outliers[:5])
        behind = [res.station_names[i] for i in res.outliers
                  if not np.isfinite(res.after_px[i])]
        how = ("left out of the final pass" if res.loss != "linear"
               else "kept (use --loss huber to leave them out)" if not behind else
               f"kept but {', '.join(behind[:5])}, whose board would be behind the camera, "
               "left out (use --loss huber to leave them all out)")
        diagnostics.warn("outliers", f"{len(res.outliers)} station(s) fit far worse than the "
                         f"others ({names}{', ...' if len(res.outliers) > 5 else ''}): {how}; "
                         "a wrong joint reading or a mis-detected board?")
        if len(res.outliers) > 0.3 * n:
            diagnostics.warn("many-outliers", f"{len(res.outliers)} of {n} stations flagged as "
                             "outliers: the joints may be in another unit or order than the "
                             "images")
    s, se = length_scale(res)
    uneven = uneven_lengths(res, s)
    if uneven:  # no board size explains it
        if not res.outliers:
            shown = ", ".join(f"{k} {v:+.4g}" for k, v in uneven[:4])
            u = res.nominal_model.length_unit
            diagnostics.warn("initial-error",
                             f"the images fit model {res.nominal_model.name!r} only with its "
                             f"lengths changed unevenly beyond its tolerances ({shown} {u} "
                             "beyond a common scale; a wrong board size would scale them all "
                             "alike): the stations are probably of another robot, or the "
                             "wrong model (or joints in another order or with other zero "
                             "offsets)")
        return
    if abs(s - 1.0) > max(BOARD_SCALE_LIMIT, 5.0 * se):
        diagnostics.warn("board-scale",
                         f"the identified lengths are {100 * (s - 1):+.2f} % off nominal all "
                         "together: the images take their scale from the board, so the "
                         f"--board square size is probably {100 * abs(1 / s - 1):.2f} % too "
                         f"{'small' if s < 1 else 'large'} (measure the printed squares)")
