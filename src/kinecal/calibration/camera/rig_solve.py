"""`calibrate_rig`: one bundle adjustment over the model's parameters, every camera mount,
every board mount and (optionally) each camera's intrinsics, on the corner pixels.

The rig's pixels are one residual block (`kinecal.calibration.camera.rig_block.RigBlock`)
of the stacked calibration of `kinecal.calibration.blocks`, which decides the identifiable
free set, estimates the corner noise and fits; this function adds the rig's own figures:

1. start: PnP per image, a closed form per camera-board pair, relations for the pairs
   that do not move (`kinecal.calibration.camera.rig_start`);
2. the mounts refined with the model at nominal: the "before" of every image;
3. the stacked calibration (`kinecal.calibration.blocks.calibrate_blocks`);
4. the mounts' covariance (the fit's normal equations, every free parameter with them)
   and the camera-to-camera extrinsics of cameras on one link with their uncertainty;
5. which mount takes up each held parameter (`kinecal.calibration.camera.rig_identify`);
6. held-out images of any camera: reprojection with the model nominal and calibrated.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.blocks.api import RANK_TOL, calibrate_blocks
from kinecal.calibration.blocks.stack import StackedProblem, fit_nuisance
from kinecal.calibration.camera.rig_block import RigBlock
from kinecal.calibration.camera.rig_frames import LinkFrames
from kinecal.calibration.camera.rig_identify import rig_identifiability
from kinecal.calibration.camera.rig_pixels import Mount, RigPixels, RigViews
from kinecal.calibration.camera.rig_result import RigResult
from kinecal.errors import InputError
from kinecal.optimize.lsq import LOSSES
from kinecal.spatial import axis_angle_from_matrix, invert_transform, matrix_from_axis_angle

Array = NDArray[np.float64]

__all__ = ["add_validation", "calibrate_rig"]


def calibrate_rig(model, views: RigViews, cameras: Sequence[Mount], boards: Sequence[Mount],
                  K: Sequence[Array], dist: Sequence[Array | None], *,
                  refine_intrinsics: bool | Sequence[bool] = False, rational: bool = False,
                  free: str | Sequence[str] = "identifiable", loss: str = "linear",
                  f_scale: float | None = None, validate: RigViews | None = None,
                  method: str = "park", rank_tol: float = RANK_TOL,
                  board_specs: Sequence[str] | None = None, others: Sequence = (),
                  sigma: Sequence[float | None] | None = None,
                  extra: dict[str, Any] | None = None) -> RigResult:
    """Calibrate a model and its camera rig on the corner pixels (module docstring).

    Parameters
    ----------
    model : SerialModel or SystemModel
        Nominal model (its length unit is the boards').
    views : RigViews
        The used images: cameras, joints, corners and PnP board poses.
    cameras, boards : sequence of Mount
        With resolved links (`kinecal.calibration.camera.rig_frames.check_link`).
    K, dist : sequence
        Each camera's matrix and distortion (start values where refined).
    refine_intrinsics : bool or sequence of bool
        Free intrinsics, for every camera or per camera.
    rational : bool
        12 intrinsics (``k4..k6``) instead of 9 where free.
    free, loss, f_scale, rank_tol
        As `kinecal.calibration.blocks.calibrate_blocks`.
    validate : RigViews, optional
        Held-out images of any camera (their reprojection before and after).
    method : str
        Hand-eye closed form of the start.
    board_specs : sequence of str, optional
        The boards' specs (reported).
    others : sequence, optional
        Further measurement sets of the same model (tracker points, ballbar, sockets,
        planes: `kinecal.io.kinds.read_kind`): one problem with the pixels (the tracker
        then sees the base and tool the cameras cannot).
    sigma : sequence of float or None, optional
        Their stated noise (length unit), one per set of `others`.
    extra : dict, optional
        Entries added to the JSON.

    Returns
    -------
    RigResult
    """
    with diagnostics.collect(python_warnings=True) as found:
        res = _calibrate(model, views, list(cameras), list(boards), list(K), list(dist),
                         refine_intrinsics, rational, free, loss, f_scale, validate, method,
                         rank_tol, board_specs, list(others), sigma)
    res.warnings = list(found)
    res.extra.update(extra or {})
    return res


def _calibrate(model, views, cameras, boards, K, dist, refine, rational, free, loss, f_scale,
               validate, method, rank_tol, board_specs, others, sigma) -> RigResult:
    t0 = time.perf_counter()
    if loss not in LOSSES:
        raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                         option="--loss")
    if len(views.q) < 3:
        raise InputError(f"{len(views.q)} usable images: calibrating from a rig's images "
                         "needs at least 3 (many more in practice: 20 per camera)")
    flags = [bool(refine)] * len(cameras) if isinstance(refine, bool | np.bool_) \
        else [bool(r) for r in refine]
    n_int = [(12 if rational else 9) if f else 0 for f in flags]
    block = RigBlock(views, cameras, boards, K, dist, n_int, method=method)
    p0 = model.nominal
    nu0 = block.start(model, p0)
    nu_he, _ = fit_nuisance(block, model, p0, nu0)
    before = block.pixels.image_rms(block.pixels.residuals(p0, nu_he, strict=False))
    he = block.pixels.unpack(nu_he)
    block.set_references(he[0], he[1], he[2], he[3])  # the fit's start: no second search
    sig = [None, *(sigma if sigma is not None else [None] * len(others))]
    fit = calibrate_blocks(model, [block, *others], sigma=sig, free=free, loss=loss,
                           f_scale=f_scale, rank_tol=rank_tol)
    final = _fitted_pixels(block, fit)
    zero = np.zeros(final.n_nuisance)
    after = final.image_rms(final.residuals(fit.params, zero, strict=False))
    cov = _mount_covariance(model, block, final, fit)
    sl = final.slices
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    pairs = {}
    for a in range(len(cameras)):
        for b in range(a + 1, len(cameras)):
            if cameras[a].link == cameras[b].link:
                pairs[(a, b)] = _relative(final.X0[a], final.X0[b], cov, sl["camera"][a],
                                          sl["camera"][b])
    held = [n for n in model.calibratable if n not in set(fit.free)]
    ident = rig_identifiability(final, model, fit.params, zero, fit.free, held, rank_tol,
                                fit.identifiability.confounded_with,
                                scale_known=any(b.unit == "length"
                                                for b in fit_blocks(fit, others)))
    val = _validation(model, validate, cameras, boards, he, final, fit.params)
    sigma_px = float(fit.extra["kinds"][0]["sigma"] or np.nan)
    outliers = sorted({int(i) for i in fit.outliers if i < block.n_obs})
    return RigResult(
        fit=fit, cameras=cameras, boards=boards,
        board_specs=list(board_specs or [""] * len(boards)),
        camera_poses=list(final.X0), board_poses=list(final.Y0),
        camera_sigma=[std[s] for s in sl["camera"]], board_sigma=[std[s] for s in sl["board"]],
        K=final.K, dist=final.d8, intrinsics_free=flags,
        intrinsics_sigma=[std[s] if k else None for s, k in zip(sl["intrinsics"], n_int,
                                                                 strict=True)],
        pairs=pairs, identifiability=ident, names=list(views.names),
        camera_of=np.asarray(views.camera), before_px=before, after_px=after,
        outliers=outliers, sigma_px=sigma_px,
        val_names=[] if validate is None else list(validate.names),
        val_camera=None if validate is None else np.asarray(validate.camera),
        val_before_px=None if val is None else val[0],
        val_after_px=None if val is None else val[1],
        seconds=time.perf_counter() - t0, start_mounts=he)


def fit_blocks(fit, others: Sequence) -> list:
    """The measurement sets beside the rig's pixels, as blocks (their units)."""
    from kinecal.calibration.blocks.make import make_blocks

    return make_blocks(fit.nominal_model, list(others)) if others else []


def _fitted_pixels(block: RigBlock, fit) -> RigPixels:
    """The rig with its references at the fit's mounts and intrinsics (zero increments)."""
    un = {u["name"]: u for u in fit.extra["kinds"][0]["unknowns"]}
    X = [np.array(un[f"camera {c.name}"]["matrix"]) for c in block.cameras]
    Y = [np.array(un[f"board {b.name}"]["matrix"]) for b in block.boards]
    K = [np.array(un[f"{c.name} intrinsics"]["K"]) if k else Kc
         for c, k, Kc in zip(block.cameras, block.n_int, block.pixels.K, strict=True)]
    d = [np.array(un[f"{c.name} intrinsics"]["dist"]) if k else dc
         for c, k, dc in zip(block.cameras, block.n_int, block.pixels.d8, strict=True)]
    return RigPixels(block.frames, block.views, block.cameras, block.boards, K, d, X, Y,
                     block.n_int)


def _mount_covariance(model, block: RigBlock, final: RigPixels, fit) -> Array:
    """Covariance ``(n_nu, n_nu)`` of the rig's unknowns at the solution, every free
    parameter of the model estimated with them (the fit's normal equations, the noise
    scaled by the residual's)."""
    sub = RigBlock(block.views, block.cameras, block.boards, final.K, final.d8, block.n_int,
                   frames=block.frames)
    sub.set_references(final.X0, final.Y0)
    s = float(fit.extra["kinds"][0]["sigma"] or 1.0)
    prob = StackedProblem(model, [sub], list(fit.free), [np.full(sub.n_obs, s)], fit.params)
    x = prob.pack(fit.params, [np.zeros(sub.n_nuisance)])
    r, A, _ = prob.normal_equations(x)
    d = np.sqrt(np.clip(np.diag(A), 1e-300, None))
    inv = np.linalg.pinv(A / d[:, None] / d[None, :], rcond=1e-12, hermitian=True)
    inv = inv / d[:, None] / d[None, :]
    dof = max(r.size - prob.n, 1)
    s2 = float(r @ r) / dof
    k = prob.k
    return inv[k:, k:] * s2


def _relative(Xa: Array, Xb: Array, cov: Array, sa: slice, sb: slice
              ) -> tuple[Array, Array]:
    """Camera b in camera a ``inv(Xa) Xb`` and its standard deviations (rotation in rad
    about b's axes, translation in a's frame), the mounts' covariance propagated."""
    T0 = invert_transform(Xa) @ Xb

    def moved(v: Array) -> Array:
        A, B = Xa.copy(), Xb.copy()
        A[:3, :3] = Xa[:3, :3] @ matrix_from_axis_angle(v[:3])
        A[:3, 3] = Xa[:3, 3] + v[3:6]
        B[:3, :3] = Xb[:3, :3] @ matrix_from_axis_angle(v[6:9])
        B[:3, 3] = Xb[:3, 3] + v[9:12]
        T = invert_transform(A) @ B
        return np.r_[axis_angle_from_matrix(T0[:3, :3].T @ T[:3, :3]), T[:3, 3] - T0[:3, 3]]

    h = 1e-7
    J = np.column_stack([(moved(h * e) - moved(-h * e)) / (2 * h) for e in np.eye(12)])
    idx = np.r_[np.arange(sa.start, sa.stop), np.arange(sb.start, sb.stop)]
    C = J @ cov[np.ix_(idx, idx)] @ J.T
    return T0, np.sqrt(np.clip(np.diag(C), 0.0, None))


def add_validation(res: RigResult, views: RigViews) -> RigResult:
    """`res` with the held-out images `views` judged (their reprojection with the model
    at nominal and its mounts fitted there, and calibrated): for images whose corners
    were put in order after the calibration (a symmetric board's, `kinecal.vision`)."""
    model = res.fit.nominal_model
    final = RigPixels(None, views, res.cameras, res.boards, res.K, res.dist,
                      res.camera_poses, res.board_poses, [0] * len(res.cameras))
    val = _validation(model, views, res.cameras, res.boards, res.start_mounts, final,
                      res.params)
    if val is not None:
        res.val_names, res.val_camera = list(views.names), np.asarray(views.camera)
        res.val_before_px, res.val_after_px = val
    return res


def _validation(model, validate: RigViews | None, cameras, boards, he, final: RigPixels,
                params: Array) -> tuple[Array, Array] | None:
    """Per-image RMS of held-out images: the model at nominal with the mounts fitted there,
    and calibrated."""
    if validate is None or not len(validate.q):
        return None
    frames = LinkFrames(model, validate.q, [m.link for m in cameras + boards])
    X, Y, K, d = he
    vb = RigPixels(frames, validate, cameras, boards, K, d, X, Y, [0] * len(cameras))
    va = RigPixels(frames, validate, cameras, boards, final.K, final.d8, final.X0, final.Y0,
                   [0] * len(cameras))
    zero = np.zeros(vb.n_nuisance)
    return (vb.image_rms(vb.residuals(model.nominal, zero, strict=False)),
            va.image_rms(va.residuals(params, zero, strict=False)))
