"""`calibrate_arm_camera`: the arm, X, the board pose (and the intrinsics) from corner pixels.

The camera pixels are one residual block (`kinecal.calibration.camera.residual_block.
CameraBlock`) of the stacked calibration of `kinecal.calibration.blocks`; this function is
that calibration with the camera's own before/after figures and words around it:

1. start: X and the board pose by a hand-eye closed form on the nominal flange poses and
   the per-image board poses (`kinecal.calibration.camera.start`, the block's ``start``);
2. hand-eye refinement with the arm at nominal (X, board, intrinsics on the pixels,
   `kinecal.calibration.blocks.stack.fit_nuisance`): the "before" of the report;
3. what the pixels identify, in words (`kinecal.calibration.camera.identify`);
4. the stacked calibration (`kinecal.calibration.blocks.calibrate_blocks`): identifiable
   free set, Levenberg-Marquardt on the arm and the nuisance, the corner noise estimated,
   optional robust refit with outlier stations, covariance on the identifiable subspace.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.blocks.api import calibrate_blocks
from kinecal.calibration.blocks.stack import fit_nuisance
from kinecal.calibration.camera.block import PixelBlock
from kinecal.calibration.camera.checks import check_camera_fit
from kinecal.calibration.camera.identify import camera_identifiability
from kinecal.calibration.camera.residual_block import CameraBlock
from kinecal.calibration.camera.result import ArmCameraResult, Stations
from kinecal.calibration.diagnostics import CODES
from kinecal.calibration.diagnostics._common import chi_outliers
from kinecal.calibration.serial.problem import candidate_names
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.optimize.lsq import LOSSES

Array = NDArray[np.float64]

__all__ = ["calibrate_arm_camera"]

#: rank threshold of the arm's analysis (that of calibrate's free="identifiable")
RANK_TOL = 1e-4


def calibrate_arm_camera(
    model: SerialModel,
    stations: Stations,
    K: Array,
    dist: Array | None,
    *,
    setup: str = "eye-in-hand",
    free: str | Sequence[str] = "identifiable",
    refine_intrinsics: bool = False,
    rational: bool = False,
    loss: str = "linear",
    f_scale: float | None = None,
    validate: Stations | None = None,
    X0: Array | None = None,
    Y0: Array | None = None,
    method: str = "park",
    rank_tol: float = RANK_TOL,
    extra: dict[str, Any] | None = None,
) -> ArmCameraResult:
    """Calibrate the arm's geometry, X and the board pose on the corner pixels.

    Parameters
    ----------
    model : SerialModel
        Nominal arm (length unit = the board's).
    stations : Stations
        Joints, detected corners and (for the start) PnP board poses of the used stations.
    K, dist
        Camera matrix and OpenCV distortion coefficients.
    setup : {"eye-in-hand", "eye-to-hand"}
    free : {"identifiable", "all"} or sequence of str
        The arm's free parameters (as in `kinecal.calibrate`).
    refine_intrinsics, rational : bool
        Free ``fx, fy, cx, cy, k1, k2, p1, p2, k3`` (and ``k4..k6`` for the rational model).
    loss : str
        ``linear`` or a robust loss on each corner (`kinecal.calibration.camera.lm.LOSSES`);
        robust: outlier stations left out of a final pass.
    f_scale : float, optional
        Robust loss scale (px); default 3x the median corner error with the arm at nominal.
    validate : Stations, optional
        Held-out stations: their reprojection before (arm nominal) and after.
    X0, Y0 : ndarray, shape (4, 4), optional
        Start of X and the board pose (default: the closed form).
    method : str
        Hand-eye closed form of the start.
    rank_tol : float
        Rank threshold of the identifiability analysis.
    extra : dict, optional
        Entries added to the result's JSON (image folder, board spec, rejected images).

    Returns
    -------
    ArmCameraResult

    Raises
    ------
    InputError
        Bad arguments, fewer than 3 stations, motions that do not determine X, a board
        behind the camera (joints that do not fit the images).
    """
    with diagnostics.collect(python_warnings=True) as found:
        res = _calibrate(model, stations, K, dist, setup, free, refine_intrinsics, rational,
                         loss, f_scale, validate, X0, Y0, method, rank_tol)
    res.warnings = list(found)
    res.extra.update(extra or {})
    return res


def _calibrate(model, st, K, dist, setup, free, refine_intrinsics, rational, loss, f_scale,
               validate, X0, Y0, method, rank_tol) -> ArmCameraResult:
    t0 = time.perf_counter()
    if loss not in LOSSES:
        raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                         option="--loss")
    if len(st.q) < 3:
        raise InputError(f"{len(st.q)} usable stations: calibrating an arm from images needs "
                         "at least 3 (many more in practice: 20-40)")
    n_int = (12 if rational else 9) if refine_intrinsics else 0
    # the robust start (RANSAC and reweighted LM) for every loss: it names the stations
    # that fit no camera mount with the others, which a plain start would fit all together
    block = CameraBlock(st, K, dist, setup, n_int, method=method, robust_start=True)
    p0 = model.nominal
    if X0 is not None and Y0 is not None:
        block.set_references(model, X0, Y0)
    start = block.start(model, p0)
    # the "before" (arm nominal, X and board refined) and the analysis without the stations
    # the robust start found inconsistent: their boards may be behind the camera
    pre = block.start_outliers if len(st.q) - len(block.start_outliers) >= 3 else []
    clean = _without(block, model, pre) if pre else block
    nu_he, _ = fit_nuisance(clean, model, p0, start)
    r_he = block.pixels.residuals(p0, nu_he, strict=False)
    cands = candidate_names(model, free)
    ident = camera_identifiability(clean.pixels, p0, nu_he, cands, tol=rank_tol)
    fit, outliers = _robust_fits(model, block, free, loss, f_scale, rank_tol)
    unknowns = {u["name"]: u for u in fit.extra["kinds"][0]["unknowns"]}
    final = _fitted_pixels(model, block, fit)
    X, Y, Kf, df = final.X0, final.Y0, final.K, final.d8
    nstd = np.radians(unknowns["X"]["std_rotation_deg"]).tolist() + \
        unknowns["X"]["std_translation"] + \
        np.radians(unknowns["board"]["std_rotation_deg"]).tolist() + \
        unknowns["board"]["std_translation"]
    if n_int:
        Kf, df = np.array(unknowns["intrinsics"]["K"]), np.array(unknowns["intrinsics"]["dist"])
        nstd += unknowns["intrinsics"]["std"]
    r = final.residuals(fit.params, np.zeros(12), strict=False)
    he = block.pixels.unpack(nu_he)
    val = None
    if validate is not None and len(validate.q):
        vb = PixelBlock(model, validate.q, validate.points, validate.pixels, setup, he[2],
                        he[3], he[0], he[1])
        va = PixelBlock(model, validate.q, validate.points, validate.pixels, setup, Kf, df,
                        X, Y)
        val = (vb.station_rms(vb.residuals(p0, np.zeros(12))),
               va.station_rms(va.residuals(fit.params, np.zeros(12))))
    calibrated = fit.model
    calibrated.description = (
        f"{model.name} calibrated from {len(st.q)} camera images ({setup}); held at nominal, "
        "not seen by a camera: " + ", ".join(n for n in cands if n not in set(fit.free)))
    res = ArmCameraResult(
        model=calibrated, nominal_model=model, setup=setup, free=list(fit.free),
        params=fit.params, std=fit.std, X=X, board_pose=Y, X_handeye=he[0],
        board_handeye=he[1], K=Kf, dist=df, nuisance_names=block.nuisance_names,
        nuisance_std=np.array(nstd), identifiability=ident, uncertainty=fit.uncertainty,
        station_names=list(st.names), before_px=block.observation_errors(r_he),
        after_px=final.station_rms(r), outliers=outliers,
        sigma_px=float(fit.extra["kinds"][0]["sigma"]), loss=loss,
        val_before_px=None if val is None else val[0],
        val_after_px=None if val is None else val[1],
        residuals=np.split(-r, np.cumsum(final.counts)[:-1]), iterations=fit.iterations,
        evaluations=fit.evaluations, history=list(fit.history), success=fit.success,
        seconds=time.perf_counter() - t0)
    check_camera_fit(res)
    return res


def _robust_fits(model: SerialModel, block: CameraBlock, free, loss: str, f_scale,
                 rank_tol: float) -> tuple[Any, list[int]]:
    """The fit and its outlier stations (indices into `block`'s stations).

    The stations the robust closed-form start found inconsistent (a joint reading 20 deg
    off, swapped images, an image turned by 180 deg: they start hundreds of pixels away
    and wreck the arm's fit even down-weighted) are left out of a first fit, and every
    station is judged again at that fit (the start's judgement is coarse: the arm at
    nominal; a station it flagged that fits now is used again). Robust loss: the outliers
    are left out of the final fit (a joint read a degree off moves its corners by pixels;
    down-weighted they still pull). Linear loss: they are kept in the final fit and named,
    as the tracker path does; a fit they make impossible (a board behind the camera) is an
    error that names them."""
    n = len(block.stations.q)
    pre = sorted(block.start_outliers)
    if n - len(pre) < 3:
        pre = []
    kept = np.array([i for i in range(n) if i not in set(pre)], dtype=np.intp)
    with diagnostics.expect(*CODES) as first:  # issued below unless a final fit follows
        fit = calibrate_blocks(model, [_without(block, model, pre) if pre else block],
                               free=free, loss=loss, f_scale=f_scale, rank_tol=rank_tol)
    outliers = sorted(int(kept[i]) for i in fit.outliers)
    behind: list[int] = []
    if pre:  # every station judged again at this fit
        every = _fitted_pixels(model, block, fit)
        e = every.station_rms(every.residuals(fit.params, np.zeros(12), strict=False))
        outliers = sorted(set(outliers) | set(chi_outliers(e, block.obs_dof)))
        behind = [int(i) for i in np.flatnonzero(~np.isfinite(e))]
    robust = loss != "linear"
    if (robust and outliers != pre and n - len(outliers) >= 3) or (not robust and pre):
        # linear loss keeps every station it can: not one whose board would be behind
        # the camera (a joint reading far off), which no fit can take
        drop = outliers if robust else behind
        try:
            fit = calibrate_blocks(model, [_without(block, model, drop) if drop else block],
                                   free=free, loss=loss, f_scale=f_scale, rank_tol=rank_tol)
        except InputError as exc:
            names = ", ".join(block.stations.names[i] for i in outliers[:5])
            raise InputError(f"station(s) {names} fit no camera mount with the others (a "
                             "joint read wrong, or the image of another station); kept by "
                             f"--loss linear they make the fit impossible ({exc.message}): "
                             "check their joints and images, or leave them out with --loss "
                             "huber") from None
        if not robust:  # kept: the fit of every station flags them too, and maybe more
            outliers = sorted(set(outliers) | set(fit.outliers))
    else:
        for d in first:
            diagnostics.warn(d.code, d.message)
    return fit, outliers


def _fitted_pixels(model: SerialModel, block: CameraBlock, fit) -> PixelBlock:
    """Every station of `block` with the fit's X, board pose and intrinsics."""
    st = block.stations
    unknowns = {u["name"]: u for u in fit.extra["kinds"][0]["unknowns"]}
    K, d = block.pixels.K, block.pixels.d8
    if block.n_int:
        K, d = np.array(unknowns["intrinsics"]["K"]), np.array(unknowns["intrinsics"]["dist"])
    return PixelBlock(model, st.q, st.points, st.pixels, block.setup, K, d,
                      np.array(unknowns["X"]["matrix"]), np.array(unknowns["board"]["matrix"]))


def _without(block: CameraBlock, model: SerialModel, drop: Sequence[int]) -> CameraBlock:
    """`block` without the stations `drop`, with the same references."""
    st = block.stations
    keep = [i for i in range(len(st.q)) if i not in set(drop)]
    sub = Stations(st.q[keep], [st.points[i] for i in keep], [st.pixels[i] for i in keep],
                   None if st.target2cam is None else st.target2cam[keep],
                   [st.names[i] for i in keep])
    out = CameraBlock(sub, block.K, block.dist, block.setup, block.n_int, block.source,
                      block.sigma, block.method)
    out.set_references(model, block.pixels.X0, block.pixels.Y0)
    return out
