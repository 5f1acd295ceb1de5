"""Hand-eye calibration: kinecal's closed forms and refiners beside OpenCV's five solvers.

Synthetic eye-in-hand stations in millimetres (issue 10): 20 stations, camera noise
0.1 deg / 0.5 mm (target2cam), robot noise 0.02 deg / 0.1 mm (flange2base), each as an
isotropic Gaussian rotation vector (per component) and translation (per component)
applied in the moving frame. Camera 400 mm above the target (positions +-60 mm), looking
at it with its orientation spread by a random rotation of per-axis std ``wide`` 25 deg,
``moderate`` 10 deg, ``narrow`` 4 deg. Outlier scenario: 2 of the 20 target2cam poses
additionally corrupted by 3 deg about a random axis and 10 mm along a random direction.

Reports median rotation (deg) and translation (mm) errors of X over the trials, OpenCV
exceptions and gross failures (error > 10 deg), speed of every closed form as a ratio to
the same OpenCV method in the same process, and OpenCV ANDREFF's translation on noise-free
data in millimetres.

Noisy robot poses (`noisy_robot`): the robot's noise dominating (0.01 deg / 0.05 mm and
0.05 deg / 0.2 mm on the flange; the camera's 0.0025 deg / 0.01 mm), and exact robot poses
beside a noisy camera (0.1 deg / 0.5 mm): kinecal's default (`calibrate_handeye`, the station
noise estimated) against each OpenCV closed form, RMS and median errors over the sets,
ratio to the best OpenCV method per error kind. The same on pixels: projected corners of 20
planned views of a 9x6 chessboard (0.03 / 0.1 px noise), kinecal's refinement on the
pixels (`refine_reprojection`, robot noise estimated: its default) and the same with the
robot poses trusted (the former default) against OpenCV's ``solvePnP`` + ``calibrateHandEye``.

    python benchmarks/bench_handeye.py [--quick] [--trials N] [--meta-trials N]
                                       [--noisy-robot-only]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kinecal.calibration.handeye import calibrate_handeye, solve
from kinecal.calibration.handeye.errors import pose_error
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    matrix_from_rpy,
    transform_from,
)

try:
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
except ImportError:  # optional peer
    cv2 = None

X_TRUE = transform_from(matrix_from_rpy([0.1, -0.25, 1.3]), [30.0, -20.0, 80.0])
Y_TRUE = transform_from(matrix_from_rpy([0.0, 0.03, 0.4]), [600.0, 100.0, 0.0])
#: a result this far off (deg) is a failure (OpenCV 4.14's TSAI logs "Not enough informative
#: motions" and returns a meaningless X instead of raising)
GROSS_DEG = 10.0
SPREADS = {"wide": 25.0, "moderate": 10.0, "narrow": 4.0}
CV_METHODS = ("tsai", "park", "horaud", "andreff", "daniilidis")
KC_METHODS = ("tsai", "park", "horaud", "andreff", "daniilidis", "shah", "li")


def stations(rng, spread_deg, n=20, corrupt=0, noise=True):
    """(flange2base, target2cam) ``(n, 4, 4)`` in mm, see the module docstring."""
    look = matrix_from_rpy([np.pi, 0.0, 0.0])
    R = matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(spread_deg)) @ look
    p = np.column_stack([rng.uniform(-60, 60, (n, 2)), rng.uniform(370, 430, n)])
    cam = transform_from(R, p)  # cam2target
    C = invert_transform(cam)
    G = Y_TRUE @ cam @ invert_transform(X_TRUE)
    if noise:
        C = C @ transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(0.1)),
                               rng.normal(size=(n, 3)) * 0.5)
        G = G @ transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(0.02)),
                               rng.normal(size=(n, 3)) * 0.1)
    for i in rng.choice(n, corrupt, replace=False):
        ax = rng.normal(size=3)
        d = rng.normal(size=3)
        C[i] = C[i] @ transform_from(matrix_from_axis_angle(ax / np.linalg.norm(ax)
                                                             * np.radians(3.0)),
                                     10.0 * d / np.linalg.norm(d))
    return G, C


def opencv_x(G, C, method):
    R, t = cv2.calibrateHandEye(G[:, :3, :3], G[:, :3, 3], C[:, :3, :3], C[:, :3, 3],
                                method=getattr(cv2, "CALIB_HAND_EYE_" + method.upper()))
    return transform_from(R, t.ravel())


def run_scenario(spread, corrupt, trials, meta_trials, seed):
    rng = np.random.default_rng(seed)
    errs: dict[str, list] = {}
    fails: dict[str, int] = {}

    def add(name, X):
        errs.setdefault(name, []).append(pose_error(X, X_TRUE))

    for k in range(trials):
        G, C = stations(rng, SPREADS[spread], corrupt=corrupt)
        for m in KC_METHODS:
            add(f"kinecal {m}", solve(G, C, m)[0])
        add("kinecal park + lm", calibrate_handeye(G, C, method="park", refine="lm").X)
        if k < meta_trials:
            for ref in ("igwo", "dlh-gwo-de"):
                res = calibrate_handeye(G, C, method="park", refine=ref, seed=k)
                add(f"kinecal park + {ref}", res.X)
        if cv2 is not None:
            for m in CV_METHODS:
                try:
                    X = opencv_x(G, C, m)
                    if not np.isfinite(X).all():
                        raise ValueError("non-finite result")
                    add(f"OpenCV {m.upper()}", X)
                except (cv2.error, ValueError):
                    fails[f"OpenCV {m.upper()}"] = fails.get(f"OpenCV {m.upper()}", 0) + 1
    med = {name: [*np.median(np.array(v), axis=0).tolist(), len(v),
                  int(np.sum(np.array(v)[:, 0] > GROSS_DEG))] for name, v in errs.items()}
    return med, fails


def timing(reps, seed=0, rounds=7):
    """Per method: kinecal's closed form (`solve`), the whole `calibrate_handeye` with
    ``refine="none"`` (validation, the closed form, residuals, uncertainty and the
    plausibility checks), the same with ``robust=True`` (outlier flags judged at a robust
    pass) and OpenCV, in ms; `rounds` interleaved rounds of `reps`
    calls each, the best round of each kept."""
    rng = np.random.default_rng(seed)
    G, C = stations(rng, SPREADS["moderate"])
    Bi = invert_transform(G)

    def opencv(m):
        if m in CV_METHODS:
            return lambda: opencv_x(G, C, m)
        flag = getattr(cv2, "CALIB_ROBOT_WORLD_HAND_EYE_" + m.upper())
        return lambda: cv2.calibrateRobotWorldHandEye(C[:, :3, :3], C[:, :3, 3], Bi[:, :3, :3],
                                                      Bi[:, :3, 3], method=flag)

    out = {}
    for m in (*CV_METHODS, "shah", "li"):
        fns = {"solve": lambda m=m: solve(G, C, m),
               "none": lambda m=m: calibrate_handeye(G, C, method=m, refine="none"),
               "flags": lambda m=m: calibrate_handeye(G, C, method=m, refine="none",
                                                      robust=True),
               "cv": opencv(m)}
        best = dict.fromkeys(fns, np.inf)
        for _ in range(rounds):
            for k, fn in fns.items():
                t0 = time.perf_counter()
                for _ in range(reps):
                    fn()
                best[k] = min(best[k], (time.perf_counter() - t0) / reps)
        out[m] = (best["solve"] * 1e3, best["none"] * 1e3, best["flags"] * 1e3,
                  best["cv"] * 1e3, best["solve"] / best["cv"], best["none"] / best["cv"],
                  best["flags"] / best["cv"])
    return out


def andreff_units(trials, seed=0):
    """Noise-free: max translation error (mm) of OpenCV ANDREFF vs kinecal andreff."""
    rng = np.random.default_rng(seed)
    res = {}
    for spread in SPREADS:
        e_cv, e_kc = [], []
        for _ in range(trials):
            G, C = stations(rng, SPREADS[spread], noise=False)
            e_cv.append(pose_error(opencv_x(G, C, "andreff"), X_TRUE)[1])
            e_kc.append(pose_error(solve(G, C, "andreff")[0], X_TRUE)[1])
        res[spread] = (float(np.median(e_cv)), float(np.max(e_cv)), float(np.max(e_kc)))
    return res


def _rms_median(errs):
    a = np.asarray(errs)
    return np.sqrt(np.mean(a**2, axis=0)), np.median(a, axis=0)


def _noise_stations(rng, spread_deg, cam, rob, n=20):
    """`stations` with the given camera and robot noise (deg, mm per axis)."""
    look = matrix_from_rpy([np.pi, 0.0, 0.0])
    R = matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(spread_deg)) @ look
    cam_pose = transform_from(R, np.column_stack([rng.uniform(-60, 60, (n, 2)),
                                                  rng.uniform(370, 430, n)]))
    C = invert_transform(cam_pose) @ transform_from(
        matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(cam[0])),
        rng.normal(size=(n, 3)) * cam[1])
    G = Y_TRUE @ cam_pose @ invert_transform(X_TRUE) @ transform_from(
        matrix_from_axis_angle(rng.normal(size=(n, 3)) * np.radians(rob[0])),
        rng.normal(size=(n, 3)) * rob[1])
    return G, C


def _pixel_set(seed, rob, px):
    """Projected corners of 20 planned views (`kinecal.vision.render.plan_views`)."""
    from kinecal.calibration.handeye.camera import project
    from kinecal.vision.boards import Chessboard
    from kinecal.vision.render import plan_views

    K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
    dist = np.array([-0.12, 0.04, 0.0005, -0.0003, 0.0])
    board = Chessboard(9, 6, 20.0)
    C = plan_views(board, K, dist, (480, 360), 20, rng=seed)
    X = transform_from(matrix_from_axis_angle([0.02, -0.03, 1.5]), [70.0, -20.0, 60.0])
    Y = transform_from(matrix_from_axis_angle([np.pi, 0.0, 0.3]), [650.0, -100.0, 50.0])
    rng = np.random.default_rng(1000 + seed)
    F = Y @ invert_transform(C) @ invert_transform(X) @ transform_from(
        matrix_from_axis_angle(rng.normal(size=(20, 3)) * np.radians(rob[0])),
        rng.normal(size=(20, 3)) * rob[1])
    pts = [board.object_points] * 20
    pix = [project(K, dist, board.object_points @ c[:3, :3].T + c[:3, 3])
           + rng.normal(scale=px, size=(board.n_corners, 2)) for c in C]
    return F, pts, pix, K, dist, X


def noisy_robot(trials, pixel_trials, seed=0):
    """Rows (case, what, RMS ratio, median ratio to OpenCV's best) of the module
    docstring's noisy-robot study."""
    from kinecal.calibration.handeye.images import refine_reprojection
    from kinecal.diagnostics import collect

    out = []
    cases = [("robot 0.01 deg / 0.05 mm", (0.0025, 0.01), (0.01, 0.05)),
             ("robot 0.05 deg / 0.2 mm", (0.0025, 0.01), (0.05, 0.2)),
             ("exact robot, camera 0.1 deg / 0.5 mm", (0.1, 0.5), (0.0, 0.0))]
    for name, cam, rob in cases:
        for spread in SPREADS:
            rng = np.random.default_rng(seed)
            ours, cv = [], []
            for _ in range(trials):
                G, C = _noise_stations(rng, SPREADS[spread], cam, rob)
                with collect():
                    ours.append(pose_error(calibrate_handeye(G, C).X, X_TRUE))
                cv.append([pose_error(opencv_x(G, C, m), X_TRUE) for m in CV_METHODS[:3]])
            (o_r, o_m), (c_r, c_m) = _rms_median(ours), _rms_median(cv)
            out.append((f"poses, {name}, {spread}", "kinecal default",
                        o_r / c_r.min(axis=0), o_m / c_m.min(axis=0), o_r, c_r.min(axis=0)))
    for rob, px in (((0.01, 0.05), 0.03), ((0.01, 0.05), 0.1), ((0.05, 0.2), 0.05),
                    ((0.0, 0.0), 0.05)):
        ours, old, cv = [], [], []
        for k in range(pixel_trials):
            F, pts, pix, K, dist, X = _pixel_set(seed + k, rob, px)
            C = []
            for P, uv in zip(pts, pix, strict=True):
                _, rv, tv = cv2.solvePnP(P, uv, K, dist)
                C.append(transform_from(cv2.Rodrigues(rv)[0], tv.ravel()))
            C = np.array(C)
            with collect():
                s0 = calibrate_handeye(F, C, refine="none", robust=False)
                ours.append(pose_error(refine_reprojection(F, pts, pix, K, dist, s0.X,
                                                           s0.target).X, X))
                old.append(pose_error(refine_reprojection(F, pts, pix, K, dist, s0.X,
                                                          s0.target, robot_noise=None).X, X))
            cv.append([pose_error(opencv_x(F, C, m), X) for m in CV_METHODS[:3]])
        c_r, c_m = _rms_median(cv)
        name = f"pixels, robot {rob[0]:g} deg / {rob[1]:g} mm, corners {px:g} px"
        for label, e in (("kinecal default (robot noise estimated)", ours),
                         ("robot poses trusted (former default)", old)):
            o_r, o_m = _rms_median(e)
            out.append((name, label, o_r / c_r.min(axis=0), o_m / c_m.min(axis=0), o_r,
                        c_r.min(axis=0)))
    return out


def print_noisy_robot(trials, pixel_trials, seed):
    print(f"\n## noisy robot poses ({trials} pose sets, {pixel_trials} pixel sets per case; "
          "ratio = kinecal / the best of OpenCV TSAI, PARK, HORAUD per error kind)\n")
    print("| case | kinecal | RMS rotation ratio | RMS translation ratio | median rotation "
          "ratio | median translation ratio | kinecal RMS (deg / mm) | OpenCV best RMS |")
    print("|---|---|---|---|---|---|---|---|")
    for case, what, rr, mr, o, c in noisy_robot(trials, pixel_trials, seed):
        print(f"| {case} | {what} | {rr[0]:.2f} | {rr[1]:.2f} | {mr[0]:.2f} | {mr[1]:.2f} | "
              f"{o[0]:.4f} / {o[1]:.4f} | {c[0]:.4f} / {c[1]:.4f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="10 trials, 3 with metaheuristics")
    ap.add_argument("--trials", type=int, default=None)
    ap.add_argument("--meta-trials", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--noisy-robot-only", action="store_true",
                    help="only the noisy-robot study (module docstring)")
    args = ap.parse_args()
    if args.noisy_robot_only:
        print_noisy_robot(20 if args.quick else 100, 4 if args.quick else 16, args.seed)
        return
    trials = args.trials or (10 if args.quick else 100)
    meta = args.meta_trials if args.meta_trials is not None else (3 if args.quick else 10)
    print(f"# hand-eye benchmark: {trials} trials per scenario (metaheuristics: first {meta}),"
          " 20 stations, camera noise 0.1 deg / 0.5 mm, robot noise 0.02 deg / 0.1 mm")
    if cv2 is None:
        print("(OpenCV not installed: peer columns skipped)")
    t_start = time.perf_counter()
    for corrupt in (0, 2):
        for spread in SPREADS:
            med, fails = run_scenario(spread, corrupt, trials, meta, args.seed)
            title = f"{spread} spread ({SPREADS[spread]:g} deg)"
            title += ", 2 corrupted stations (3 deg / 10 mm)" if corrupt else ", no outliers"
            print(f"\n## {title}\n")
            print("| solver | median rotation error (deg) | median translation error (mm) | n "
                  f"| failures (> {GROSS_DEG:g} deg) |")
            print("|---|---|---|---|---|")
            for name, (r, t, n, gross) in med.items():
                print(f"| {name} | {r:.4f} | {t:.3f} | {n} | {gross} |")
            cv_best = [v for k, v in med.items() if k.startswith("OpenCV")]
            if cv_best:
                br = min(v[0] for v in cv_best)
                bt = min(v[1] for v in cv_best)
                lm = med["kinecal park + lm"]
                print(f"\nlm vs OpenCV's best: rotation {br / lm[0]:.2f}x lower, translation "
                      f"{bt / lm[1]:.2f}x lower ({100 * (1 - lm[1] / bt):.0f} % better)")
            if fails:
                text = ", ".join(f"{k} {v}/{trials}" for k, v in fails.items())
                print(f"OpenCV exceptions: {text}")
    if cv2 is not None:
        print("\n## speed (20 stations, all 190 pairs; ratio = kinecal / OpenCV, same process, "
              "best of interleaved rounds)\n")
        print("| method | closed form (ms) | calibrate_handeye refine=none (ms) | the same, "
              "robust=True (ms) | OpenCV (ms) | closed form / OpenCV | refine=none / OpenCV "
              "| robust=True / OpenCV |")
        print("|---|---|---|---|---|---|---|---|")
        for m, (tk, tn, tf, tc, r, rn, rf) in timing(10 if args.quick else 50).items():
            print(f"| {m} | {tk:.3f} | {tn:.3f} | {tf:.3f} | {tc:.3f} | {r:.2f} | {rn:.2f} "
                  f"| {rf:.2f} |")
        print("\n## ANDREFF, noise-free, millimetres: translation error (mm)\n")
        print("| spread | OpenCV median | OpenCV max | kinecal max |")
        print("|---|---|---|---|")
        for s, (a, b, c) in andreff_units(10 if args.quick else 50).items():
            print(f"| {s} | {a:.3g} | {b:.3g} | {c:.2g} |")
    if cv2 is not None:
        print_noisy_robot(20 if args.quick else 100, 4 if args.quick else 16, args.seed)
    print(f"\n(total {time.perf_counter() - t_start:.0f} s)")


if __name__ == "__main__":
    main()
