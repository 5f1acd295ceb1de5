"""Hand-eye calibration (paper 001, ``papers/001``): closed forms, refinement, residuals.

Entry point: `calibrate_handeye`. Input conventions are OpenCV's ``calibrateHandEye``:

- eye-in-hand (camera on the flange): pass ``flange2base`` and ``target2cam``; the result
  ``X`` is ``cam2flange`` and the fixed target pose ``Y`` is ``target2base``;
- eye-to-hand (camera fixed, target on the flange): the same two inputs; the result ``X``
  is ``cam2base`` and ``Y`` is ``target2flange``.

In both cases ``G_i X C_i = Y`` with ``C_i = target2cam`` and ``G_i = flange2base``
(eye-in-hand) or ``base2flange`` (eye-to-hand); see docs/handeye.md.

Stations whose robot rotations all turn about one axis (SCARA, 4-axis arms) are recognised
and solved by Ulrich & Steger (2016) (`kinecal.calibration.handeye.scara`), the height along
the axis taken from ``camera_height`` or ``board_contact``.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal import diagnostics
from kinecal.calibration.handeye import axxb, axzb
from kinecal.calibration.handeye._motions import as_transforms, check_motions, motion_pairs
from kinecal.calibration.handeye.errors import (
    axxb_station_rms,
    mean_target_pose,
    station_residuals,
)
from kinecal.calibration.handeye.result import HandEyeResult
from kinecal.calibration.handeye.scara import AxisHeight, detect_one_axis
from kinecal.calibration.method_options import check_refine_options
from kinecal.errors import InputError
from kinecal.spatial import invert_transform

Array = NDArray[np.float64]

__all__ = ["METHODS", "REFINERS", "SETUPS", "HandEyeResult", "calibrate_handeye",
           "robust_solve", "solve"]

#: Closed-form methods: the five AX = XB ones and the two AX = ZB ones.
METHODS: tuple[str, ...] = (*axxb.SOLVERS, *axzb.SOLVERS)
REFINERS: tuple[str, ...] = ("none", "lm", "igwo", "dlh-gwo-de")
SETUPS: tuple[str, ...] = ("eye-in-hand", "eye-to-hand")
_META_OPTIONS = {"popsize", "maxiter", "rotation_box", "translation_box", "maxfev", "length",
                 "method_options"}


def _choice(value: str, valid: tuple[str, ...], option: str) -> str:
    if value not in valid:
        raise InputError(f"unknown {option} {value!r}; expected one of {', '.join(valid)}",
                         option=option)
    return value


def solve(G: Array, C: Array, method: str = "tsai", pairs: str = "all") -> tuple[Array, Array]:
    """Closed-form ``X`` and target pose ``Y`` from ``G_i X C_i = Y``.

    Parameters
    ----------
    G : ndarray, shape (n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand).
    C : ndarray, shape (n, 4, 4)
        ``target2cam``.
    method : str
        One of `METHODS`.
    pairs : {"all", "consecutive"}
        Motion pairs for the AX = XB methods (ignored by shah and li).

    Returns
    -------
    X, Y : ndarray, shape (4, 4)
    """
    _choice(method, METHODS, "method")
    return _solve(G, C, method, pairs)[:2]


def _solve(G: Array, C: Array, method: str, pairs: str
           ) -> tuple[Array, Array, Array | None, Array | None]:
    """`solve`, and the motion pairs ``A, B`` it used (None for the AX = ZB methods)."""
    # motions relative to station 0 suffice to detect degeneracy: if all of them turn about
    # one axis, so does every pair
    A0 = invert_transform(G[:1]) @ G[1:]
    B0 = C[:1] @ invert_transform(C[1:])
    check_motions(A0, "robot motions")
    check_motions(B0, "camera motions")
    if method in axxb.SOLVERS:
        A, B = motion_pairs(G, C, pairs)
        X = axxb.SOLVERS[method](A, B)
        return X, mean_target_pose(G, X, C), A, B
    # A_i X' = Z' B_i with A_i = C_i, B_i = G_i^-1, X' = Y^-1, Z' = X^-1
    Xp, Zp = axzb.SOLVERS[method](C, invert_transform(G))
    return invert_transform(Zp), invert_transform(Xp), None, None


def calibrate_handeye(
    flange2base: ArrayLike,
    target2cam: ArrayLike,
    *,
    setup: str = "eye-in-hand",
    method: str = "park",
    refine: str = "lm",
    pairs: str = "all",
    seed: int | np.random.Generator | None = None,
    robust: bool | None = None,
    rotation_weight: float | None = None,
    options: dict[str, Any] | None = None,
    camera_height: float | None = None,
    board_contact: ArrayLike | None = None,
) -> HandEyeResult:
    """Hand-eye calibration from pose pairs (OpenCV's input conventions).

    Parameters
    ----------
    flange2base : array_like, shape (n, 4, 4)
        Robot flange poses in the base frame, length unit L (n >= 3).
    target2cam : array_like, shape (n, 4, 4)
        Target poses in the camera frame, length unit L.
    setup : {"eye-in-hand", "eye-to-hand"}
        Camera on the flange (X = cam2flange) or fixed (X = cam2base).
    method : str
        Closed form: ``tsai``, ``park``, ``horaud``, ``andreff``, ``daniilidis`` (AX = XB)
        or ``shah``, ``li`` (AX = ZB). Default ``park`` (least squares on the rotation
        logarithms, sign-free; identical to OpenCV's PARK).
    refine : {"none", "lm", "igwo", "dlh-gwo-de"}
        ``none``: the closed form alone; ``lm`` (default): robust joint refinement of X
        and the target pose (`refine.lm`);
        ``igwo`` / ``dlh-gwo-de``: paper 001's metaheuristic refinement (sec. 4).
    pairs : {"all", "consecutive"}
        Motion pairs of the AX = XB closed forms: all i < j (OpenCV) or consecutive
        stations (paper 001, eq. (2)).
    seed : int or Generator, optional
        Random seed of the metaheuristic refiners.
    robust : bool, optional
        ``lm``: Cauchy reweighting and outlier flagging (default True). ``none``: True
        judges outlier stations at a robust refinement from the closed form
        (`refine.flag_outliers`; its X is not kept); the default (False) is the closed
        form alone, as fast as OpenCV's, with no outlier flags; every other check runs
        either way. False with ``lm``: plain least squares, no outlier flags.
    rotation_weight : float, optional
        ``lm`` only: length units per radian (default: from the residual scales).
    options : dict, optional
        Metaheuristic options (``popsize``, ``maxiter``, ``rotation_box``,
        ``translation_box``, ``maxfev``, ``length``, ``method_options``), see
        `refine_meta.metaheuristic`.
    camera_height, board_contact : optional
        Stations turning about one axis only (SCARA): X's translation along it, which AX = XB
        cannot see, or a point (3,) of the board plane touched by the tool (base frame
        eye-in-hand, flange frame eye-to-hand); `kinecal.calibration.handeye.scara`.

    Returns
    -------
    HandEyeResult

    Raises
    ------
    InputError
        Bad shapes, non-rigid transforms, unknown names, fewer than 3 distinct stations or
        degenerate motions (pure translations, or rotations about one line only).
    TypeError
        A path or name where poses are expected.

    Notes
    -----
    The plausibility checks of `kinecal.calibration.diagnostics.handeye` run on every call
    (duplicated or few stations, robot and target lengths in different units, rotation
    axes too close to parallel for the noise); their findings are in ``warnings`` and are
    issued as `kinecal.diagnostics.KinecalWarning` unless an outer collector takes them.
    """
    for name, poses in (("flange2base", flange2base), ("target2cam", target2cam)):
        if isinstance(poses, str | bytes | os.PathLike):
            raise TypeError(f"{name}: expected an array (n, 4, 4) of poses, got the path or name "
                            f"{os.fsdecode(poses)!r}; read a pairs file with "
                            "kinecal.io.handeye.read_handeye_pairs(path) (or "
                            "read_handeye_files(robot, target))")
    with diagnostics.collect(python_warnings=True) as found:
        res = _calibrate_handeye(flange2base, target2cam, setup, method, refine, pairs, seed,
                                 robust, rotation_weight, options,
                                 AxisHeight.from_options(camera_height, board_contact))
    res.warnings = list(found)
    return res


def _calibrate_handeye(flange2base, target2cam, setup, method, refine, pairs, seed, robust,
                       rotation_weight, options, height) -> HandEyeResult:
    t0 = time.perf_counter()
    if robust is None:  # outlier stations are judged by a refinement: none for "none"
        robust = refine != "none"
    F, C = _checked_inputs(flange2base, target2cam, setup, method, refine, robust,
                           rotation_weight, options)
    G = F if setup == "eye-in-hand" else invert_transform(F)
    axis = detect_one_axis(G, setup)
    if axis is not None:  # SCARA: Ulrich & Steger, the height from the caller
        from kinecal.calibration.handeye.one_axis import calibrate_one_axis

        s = calibrate_one_axis(F, C, G, setup, axis, height, refine, robust, rotation_weight,
                               seed, pairs, _meta_options(options))
        res = HandEyeResult(s.X, s.Y, setup, "ulrich-steger", refine, *s.residuals,
                            s.outliers, s.history, s.nfev, time.perf_counter() - t0)
        res.x_uncertainty, res.one_axis = s.uncertainty, s.summary
        return res
    X0, Y0, A, B = _solve(G, C, method, pairs)
    if height.given:
        from kinecal.calibration.handeye.one_axis import warn_height_unused

        warn_height_unused(height, G)
    X, Y, outliers, history, nfev, noise = _refined(G, C, X0, Y0, refine, robust,
                                                    rotation_weight, seed, pairs, options,
                                                    setup == "eye-in-hand")
    res = _judged(F, C, G, X, Y, X0, A, B, setup, method, refine, pairs, robust, outliers,
                  noise)
    res.history, res.nfev, res.seconds = history, nfev, time.perf_counter() - t0
    return res


def _checked_inputs(flange2base, target2cam, setup, method, refine, robust, rotation_weight,
                    options) -> tuple[Array, Array]:
    """Every argument checked before any work; the poses as ``(n, 4, 4)`` transforms."""
    from kinecal.calibration.diagnostics.handeye import check_handeye_stations

    _choice(setup, SETUPS, "setup")
    _choice(method, METHODS, "method")
    _choice(refine, REFINERS, "refine")
    check_refine_options(refine, robust=robust, rotation_weight=rotation_weight,
                         options=options)
    F = as_transforms(flange2base, "flange2base")
    C = as_transforms(target2cam, "target2cam")
    if len(F) != len(C):
        raise InputError(f"flange2base has {len(F)} poses but target2cam has {len(C)}")
    if len(F) < 3:
        raise InputError(f"{len(F)} stations given; hand-eye calibration needs at least 3")
    check_handeye_stations(F, C)
    if rotation_weight is not None and not (np.isfinite(rotation_weight) and rotation_weight > 0):
        raise InputError(f"rotation_weight {rotation_weight}: expected a positive length per "
                         "radian", option="rotation_weight")
    return F, C


def _refined(G, C, X, Y, refine, robust, rotation_weight, seed, pairs, options,
             eye_in_hand=True):
    """The refinement of the closed form (X, Y): ``(X, Y, outliers, history, nfev,
    noise)``; the outliers and the station noise model of ``lm`` (others are judged in
    `_judged`)."""
    if refine == "lm":
        from kinecal.calibration.handeye.refine import lm

        res = lm(G, C, X, Y, robust=robust, rotation_weight=rotation_weight,
                 eye_in_hand=eye_in_hand)
        if robust:
            res = _consensus_refinement(G, C, res, seed, rotation_weight, eye_in_hand)
        return res.X, res.Y, res.outliers, res.history, res.nfev, res.noise
    if refine in ("igwo", "dlh-gwo-de"):
        from kinecal.calibration.handeye.refine_meta import metaheuristic

        res = metaheuristic(G, C, X, refine, rng=seed, pairs=pairs, **_meta_options(options))
        return res.X, mean_target_pose(G, res.X, C), [], res.history, res.nfev, None
    return X, Y, [], [], 0, None


def _judged(F, C, G, X, Y, X0, A, B, setup, method, refine, pairs, robust,
            outliers, noise=None) -> HandEyeResult:
    """Station residuals, outliers of results not refined by ``lm`` (``robust``), the
    uncertainty of X, conditioning, and stations that fit no X (a mix-up, a unit factor)."""
    from kinecal.calibration.diagnostics.handeye import (
        check_handeye_conditioning,
        check_handeye_units,
        handeye_uncertainty,
    )
    from kinecal.calibration.diagnostics.handeye_consistency import (
        find_inconsistency,
        station_scores,
        warn_inconsistent,
    )

    shared = None
    if refine != "lm":
        from kinecal.calibration.handeye.refine import flag_outliers, residuals_and_jacobian

        # one evaluation of the camera residuals and their Jacobian serves the outlier flags,
        # the station residuals (|log| and |t| of the same mismatch) and the uncertainty
        shared = residuals_and_jacobian(G, C, X, Y, np.zeros(12))
        outliers = flag_outliers(G, C, X, Y) if robust else []
        rot = np.degrees(np.linalg.norm(shared[0], axis=1))
        tr = np.linalg.norm(shared[1], axis=1)
    else:
        rot, tr = station_residuals(G, X, C, Y)
    # the motion pairs of the closed form serve the A X - X B residuals (no second copy)
    arot, atr = axxb_station_rms(G, C, X, motions=(A, B) if pairs == "all" and A is not None
                                 else None)
    inliers = np.setdiff1d(np.arange(len(G)), outliers) if outliers else None
    if inliers is not None and len(inliers) < 3:
        inliers = None
    unc = handeye_uncertainty(G, C, X, Y, inliers,
                              residuals=shared if inliers is None else None,
                              noise=None if noise is None or noise.source != "estimated"
                              else (noise, setup == "eye-in-hand"))
    check_handeye_conditioning(unc, G if inliers is None else G[inliers])
    # stations that fit no X: a mix-up that makes them fit is named first; else a unit
    # factor between robot and target (`scale-mismatch`); else the generic warning
    inc = find_inconsistency(F, C, setup, X, Y, method, scores=station_scores(rot, tr, C))
    if inc is not None and inc.fits_with is not None:
        warn_inconsistent(inc)
    elif not check_handeye_units(G, C, X0) and inc is not None:
        warn_inconsistent(inc)
    res = HandEyeResult(X, Y, setup, method, refine, rot, tr, arot, atr, outliers, [], 0)
    res.x_uncertainty, res.noise = unc, noise
    return res


def _meta_options(options: dict[str, Any] | None) -> dict[str, Any]:
    """The metaheuristic refiners' options, unknown names refused."""
    opts = dict(options or {})
    unknown = sorted(set(opts) - _META_OPTIONS)
    if unknown:
        raise InputError(f"unknown option(s) {', '.join(unknown)}; expected "
                         f"{', '.join(sorted(_META_OPTIONS))}", option="options")
    return opts


def _consensus_refinement(G: Array, C: Array, first: Any, seed: Any,
                          rotation_weight: float | None, eye_in_hand: bool = True) -> Any:
    """Also refine from a RANSAC start on minimal sets
    (`ransac.consensus_start`) and keep whichever solution fits the best 40 % of the
    stations clearly better (least trimmed squares, common scales, 10 % margin): at 50 %
    outliers the start
    from all stations is pulled too far for reweighting to recover (KNOWN-DEFECTS: 4.75
    vs 2.45 mm); below about 35 % both end at the same solution."""
    from kinecal.calibration.handeye.ransac import TRIM, _distances, consensus_start
    from kinecal.calibration.handeye.refine import lm

    cs = consensus_start(G, C, first.scales, seed=0 if seed is None else seed)
    if cs is None:
        return first
    second = lm(G, C, cs.X, cs.Y, robust=True, rotation_weight=rotation_weight,
                start_inliers=cs.inliers, eye_in_hand=eye_in_hand)
    sr, st = second.scales
    k = max(3, int(np.ceil(TRIM * len(G))))

    def trimmed(r: Any) -> float:
        return float(np.sum(np.sort(_distances(G, C, r.X, r.Y, sr, st))[:k]))

    second.nfev += first.nfev
    # a clear margin: where both starts end at equivalent solutions, keep the first
    return second if trimmed(second) < 0.9 * trimmed(first) else first


def robust_solve(G: Array, C: Array, method: str = "park", seed: int = 0) -> tuple[Array, Array]:
    """X and Y by a closed form and the robust refinement with its RANSAC start, without
    the plausibility checks of `calibrate_handeye` (for internal consistency tests such as
    telling a turned symmetric board from the robot poses).

    Parameters
    ----------
    G, C : ndarray, shape (n, 4, 4)
        Robot poses (``flange2base`` eye-in-hand, ``base2flange`` eye-to-hand) and
        ``target2cam``, n >= 3.
    method : str
        Closed form of the start.
    seed : int
        Seed of the RANSAC sampling.

    Returns
    -------
    X, Y : ndarray, shape (4, 4)
    """
    from kinecal.calibration.handeye.refine import lm

    axis = detect_one_axis(G, "eye-in-hand")
    if axis is not None:  # one axis: no minimal sets for RANSAC; the height does not matter
        from kinecal.calibration.handeye.scara import solve_one_axis

        X, Y = solve_one_axis(G, C, axis)
        res = lm(G, C, X, Y)
        return res.X, res.Y
    X, Y = solve(G, C, method)
    res = _consensus_refinement(G, C, lm(G, C, X, Y), seed, None)
    return res.X, res.Y
