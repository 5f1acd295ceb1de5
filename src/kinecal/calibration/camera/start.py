"""The start of the arm + camera bundle adjustment, without a user guess.

The nominal model gives the flange pose of every station, PnP gives the board pose in
every image (`kinecal.vision.pnp`); a hand-eye closed form on these pairs (``AX = XB``
eye-in-hand, ``AX = ZB`` eye-to-hand, `kinecal.calibration.handeye.calibrate_handeye`,
with its robust pose-level refinement) gives X and the board pose. The arm's geometric
errors (a millimetre, a tenth of a degree) leave the closed form a few millimetres off,
well inside the bundle adjustment's basin.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.calibration.handeye import HandEyeResult, calibrate_handeye
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

Array = NDArray[np.float64]

__all__ = ["MANY_OUTLIERS", "closed_form_start"]

#: stations the robust start may flag as outliers before the data count as not fitting the
#: model and set-up at all (the share of ``many-outliers``)
MANY_OUTLIERS = 0.3


def closed_form_start(model: SerialModel, q: Array, target2cam: Array, setup: str,
                      params: Array | None = None, method: str = "park",
                      robust: bool = True) -> tuple[Array, Array, HandEyeResult]:
    """X and the board pose from the model's flange poses and the per-image board poses.

    Parameters
    ----------
    model : SerialModel
    q : ndarray, shape (n, n_joints)
        Joint readings (rad; prismatic: length unit), n >= 3.
    target2cam : ndarray, shape (n, 4, 4)
        Board pose in every image (PnP), in the model's length unit.
    setup : {"eye-in-hand", "eye-to-hand"}
    params : ndarray, shape (n_params,), optional
        Arm parameters (default nominal).
    method : str
        Closed form (`kinecal.calibration.handeye.METHODS`).
    robust : bool
        The hand-eye solver's RANSAC start and outlier stations (slower; for data that
        may hold wrong stations).

    Returns
    -------
    X : ndarray, shape (4, 4)
        ``cam2flange`` (eye-in-hand) or ``cam2base`` (eye-to-hand).
    Y : ndarray, shape (4, 4)
        ``target2base`` (eye-in-hand) or ``target2flange`` (eye-to-hand).
    seed : HandEyeResult
        The hand-eye solution (its residuals and warnings).

    Raises
    ------
    InputError
        Fewer than 3 stations, motions that do not determine X (from the hand-eye
        solver: too little rotation between the stations), or stations that fit no X
        (``handeye-inconsistent``: the message says whether the other set-up fits).
    """
    q = np.atleast_2d(np.asarray(q, float))
    C = np.asarray(target2cam, float)
    if len(q) < 3 or len(C) != len(q):
        raise InputError(f"{len(q)} stations with joints and {len(C)} board poses: the start "
                         "needs at least 3 of each, one per station")
    F = model.fk(q, params)
    with diagnostics.expect("handeye-inconsistent", "scale-mismatch") as bad:
        seed = calibrate_handeye(F, C, setup=setup, method=method, refine="lm", robust=robust)
    _check_board_scale(model, F, C, setup, seed.X)
    if any(d.code == "handeye-inconsistent" for d in bad) and \
            not _inliers_consistent(F, C, setup, method, seed.outliers):
        raise InputError(_no_mount(model, F, C, setup, method))
    for d in bad:
        diagnostics.warn(d.code, d.message)
    return np.asarray(seed.X, float), np.asarray(seed.target, float), seed


def _inliers_consistent(F: Array, C: Array, setup: str, method: str,
                        outliers: list[int]) -> bool:
    """The stations the robust start kept fit one mount (the inconsistency it reported is
    the outliers': a station turned by 180 deg, another station's image)."""
    keep = np.setdiff1d(np.arange(len(F)), outliers)
    # a few wrong stations, not most of them (a wrong set-up or model leaves a "consistent"
    # handful by chance)
    if not len(outliers) or len(keep) < 3 or len(outliers) > MANY_OUTLIERS * len(F):
        return False
    with diagnostics.expect("handeye-inconsistent", "scale-mismatch") as bad:
        calibrate_handeye(F[keep], C[keep], setup=setup, method=method, refine="lm",
                          robust=False)
    return not any(d.code == "handeye-inconsistent" for d in bad)


def _check_board_scale(model: SerialModel, F: Array, C: Array, setup: str, X: Array) -> None:
    """Refuse a factor between the arm's translations and the camera's: the board poses
    take their lengths from the board's size (``--board``), so 2.5 for 25 mm squares puts
    every board ten times nearer (and the bundle adjustment's boards behind the camera)."""
    from kinecal.calibration.diagnostics.handeye import translation_scale
    from kinecal.spatial import invert_transform

    G = F if setup == "eye-in-hand" else invert_transform(F)
    sc = translation_scale(G, C, X)
    if sc is None or not sc.unit_factor:
        return
    raise InputError(f"the joints move the camera {sc.s:.4g} times as far as the images "
                     "measure with the board's size: the --board square size (or spacing) is "
                     f"probably {sc.s:.4g} times too {'small' if sc.s > 1 else 'large'} (in "
                     f"the model's length unit, {model.length_unit}: measure the print), or "
                     "the focal length of --intrinsics is wrong")


def _no_mount(model: SerialModel, F: Array, C: Array, setup: str, method: str) -> str:
    """Why no X fits: the other set-up, or joints that do not move the camera as the model
    says (another arm, chain, joint order or unit)."""
    other = "eye-to-hand" if setup == "eye-in-hand" else "eye-in-hand"
    with diagnostics.expect("handeye-inconsistent", "handeye-conditioning") as bad:
        calibrate_handeye(F, C, setup=other, method=method, refine="lm", robust=False)
    if not bad:
        return (f"the joints and the images fit no {setup} camera mount, but they fit "
                f"--setup {other}")
    return (f"the joints and the images fit no camera mount of model {model.name!r}: the "
            "joints move the camera otherwise than the model's chain does (joints in another "
            "order or unit, another arm, or a chain that ends before the camera: "
            "--tip-link), or the images belong to other stations")
