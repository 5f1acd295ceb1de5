"""Hand-eye from images: kinecal's pipeline beside OpenCV's on the same rendered images.

Scenes (issue 18): a known camera (800 x 600 px, fx = fy = 900 px, barrel distortion
k1 = -0.15) sees a board at 20 stations of a robot, eye-in-hand (camera 70 mm off the
flange, board on a table) or eye-to-hand (camera 1.5 m from the robot base, board 80 mm in
front of the flange), chessboard 9x6 (25 mm squares) or ChArUco 7x5 (35 mm squares,
26 mm markers, DICT_5X5_100). Views: the board spans about 55 % of the image width, tilted
up to 35 deg, any roll. Images (`kinecal.vision.render`): 2x2 supersampling, Gaussian blur
0.8 px, read noise 3 grey levels + shot noise (0.1 grey level^2 per level), gain and
gradients varied +-25 % per image; a separate noise-free run renders ideal images.

Pipelines, both with the true intrinsics (so that only the hand-eye step differs):
- OpenCV, timed as its users write it (`opencv_plain`): `findChessboardCorners` +
  `cornerSubPix` (11 x 11 window, OpenCV's tutorial settings) or
  `CharucoDetector.detectBoard`, `solvePnP` (iterative) per image, `calibrateHandEye` with
  its default method; no kinecal code inside its time. Its accuracy (`opencv_accuracy`, not
  timed): each of the five methods, chessboard corners handed over in the true order (its
  best case: it may list them from either end, which breaks its pipeline on real data), and
  kinecal's refinement run on OpenCV's corners (the refinement's share of the gain);
- kinecal: `kinecal.vision.pipeline.calibrate_handeye_images` (its detector on a thread per
  CPU and quality checks, PnP, the closed form as the seed, refinement on the reprojection
  error).

Reports the median rotation (deg) and translation (mm) error of X over the scenes for each
OpenCV method and for kinecal, kinecal against the best OpenCV method per error kind, the
corner error of both detectors against the exact projections, and the time per scene:
kinecal's pipeline and the plain OpenCV pipeline interleaved on the same images in one
process, best of `--repeat` each, ratio per scene (median and range over the scenes).
Last, end to end as processes on one written scene: `kinecal handeye-images` against a plain
OpenCV script reading the same files (`PEER_SCRIPT`).

    python benchmarks/bench_handeye_images.py [--quick] [--scenes N] [--stations N] [--repeat R]
                                              [--timing-only] [--processes-only]
"""

from __future__ import annotations

import os

# small matrices: a multi-threaded BLAS only adds contention (as in the CLI)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from kinecal.calibration.handeye import calibrate_handeye  # noqa: E402
from kinecal.calibration.handeye.camera import project  # noqa: E402
from kinecal.calibration.handeye.errors import pose_error  # noqa: E402
from kinecal.calibration.handeye.images import refine_reprojection  # noqa: E402
from kinecal.spatial import invert_transform, transform_from  # noqa: E402
from kinecal.vision.boards import parse_board  # noqa: E402
from kinecal.vision.intrinsics import CameraIntrinsics  # noqa: E402
from kinecal.vision.pipeline import calibrate_handeye_images  # noqa: E402
from kinecal.vision.render import (  # noqa: E402
    ImageConditions,
    look_at,
    render_handeye_scene,
    write_scene,
)

K = np.array([[900.0, 0.0, 399.5], [0.0, 900.0, 299.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.15, 0.06, 0.0005, -0.0003, 0.0])
SIZE = (800, 600)
BOARDS = {"chessboard": "chessboard:9x6:25", "charuco": "charuco:7x5:35:26:DICT_5X5_100"}
CV_METHODS = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")
NOISY = ImageConditions(blur=0.8, noise=3.0, shot=0.1)
CLEAN = ImageConditions()


def opencv_plain(images, flange2base, K, dist, board, setup):
    """OpenCV's pipeline as its users write it (the timed peer): its detector with the
    tutorial's sub-pixel settings, ``solvePnP`` (iterative) per image, ``calibrateHandEye``
    with its default method (TSAI; eye-to-hand: base2gripper, OpenCV's recipe). No kinecal
    code inside."""
    R_g, t_g, R_c, t_c = [], [], [], []
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001)
    obj = board.object_points.astype(np.float32)
    detector = None if board.kind == "chessboard" else cv2.aruco.CharucoDetector(board.cv_board())
    for img, f in zip(images, flange2base, strict=True):
        if detector is None:
            ok, c = cv2.findChessboardCorners(
                img, (board.cols, board.rows),
                flags=cv2.CALIB_CB_ADAPTIVE_THRESH + cv2.CALIB_CB_NORMALIZE_IMAGE)
            if not ok:
                continue
            c = cv2.cornerSubPix(img, c, (11, 11), (-1, -1), crit)
            o = obj
        else:
            c, ids, _, _ = detector.detectBoard(img)
            if ids is None or len(ids) < 6:
                continue
            o = obj[ids.ravel()]
        ok, rv, tv = cv2.solvePnP(o, c, K, dist)
        if setup == "eye-in-hand":
            R_g.append(f[:3, :3])
            t_g.append(f[:3, 3])
        else:
            R_g.append(f[:3, :3].T)
            t_g.append(-f[:3, :3].T @ f[:3, 3])
        R_c.append(cv2.Rodrigues(rv)[0])
        t_c.append(tv)
    R, t = cv2.calibrateHandEye(R_g, t_g, R_c, t_c)
    return R, t


def opencv_accuracy(scene, board):
    """Accuracy of OpenCV's pipeline (not timed): its corners, handed over in the true
    order (its best case: it may list a chessboard's corners from either end, which breaks
    its pipeline on real data), every method of ``calibrateHandEye``, and kinecal's
    refinement run on OpenCV's corners and poses (the refinement's share of the gain)."""
    F, C, cerr, obs = [], [], [], []
    for img, f, T in zip(scene.images, scene.flange2base, scene.target2cam, strict=True):
        if board.kind == "chessboard":
            ok, c = cv2.findChessboardCorners(
                img, (board.cols, board.rows),
                flags=cv2.CALIB_CB_ADAPTIVE_THRESH + cv2.CALIB_CB_NORMALIZE_IMAGE)
            if not ok:
                continue
            c = cv2.cornerSubPix(img, c, (11, 11), (-1, -1),
                                 (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001))
            c = c.reshape(-1, 2).astype(float)
            obj = board.object_points
            truth = project(scene.K, scene.dist, obj @ T[:3, :3].T + T[:3, 3])
            g = c.reshape(board.rows, board.cols, 2)
            c = min((g, g[::-1, ::-1], g[:, ::-1], g[::-1]),
                    key=lambda o: np.abs(o.reshape(-1, 2) - truth).max()).reshape(-1, 2)
        else:
            c, ids, _, _ = cv2.aruco.CharucoDetector(board.cv_board()).detectBoard(img)
            if ids is None or len(ids) < 6:
                continue
            c, obj = c.reshape(-1, 2).astype(float), board.object_points[ids.ravel()]
            truth = project(scene.K, scene.dist, obj @ T[:3, :3].T + T[:3, 3])
        cerr.append(np.sum((c - truth) ** 2, axis=1))
        obs.append((obj, c))
        ok, rv, tv = cv2.solvePnP(obj, c, scene.K, scene.dist[:5])
        F.append(f)
        C.append(transform_from(cv2.Rodrigues(rv)[0], tv.ravel()))
    F, C = np.array(F), np.array(C)
    G = F if scene.setup == "eye-in-hand" else invert_transform(F)
    out = {}
    for name in CV_METHODS:
        R, t = cv2.calibrateHandEye(G[:, :3, :3], G[:, :3, 3], C[:, :3, :3], C[:, :3, 3],
                                    method=getattr(cv2, "CALIB_HAND_EYE_" + name))
        out[name] = pose_error(transform_from(R, t.ravel()), scene.X)
    seed = calibrate_handeye(F, C, setup=scene.setup)
    ref = refine_reprojection(F, [o for o, _ in obs], [c for _, c in obs], scene.K, scene.dist,
                              seed.X, seed.target, setup=scene.setup)
    return out, np.concatenate(cerr), pose_error(ref.X, scene.X)


def kinecal_pipeline(scene, board):
    """kinecal's pipeline (the timed call) with the true intrinsics."""
    return calibrate_handeye_images(scene.images, scene.flange2base, board, setup=scene.setup,
                                    intrinsics=CameraIntrinsics(scene.K, scene.dist,
                                                                scene.size))


def kinecal_corner_errors(res, scene, board):
    cerr = []
    for rec, T in zip(res.records, scene.target2cam, strict=True):
        if rec.detection is not None and rec.detection.ok:
            obj = rec.detection.object_points(board)
            truth = project(scene.K, scene.dist, obj @ T[:3, :3].T + T[:3, 3])
            cerr.append(np.sum((rec.detection.corners - truth) ** 2, axis=1))
    return np.concatenate(cerr)


def timed_pair(scene, board, repeat):
    """Best-of-`repeat` wall and CPU times (the process's, all threads) of kinecal's
    pipeline and the plain OpenCV peer on the same images, interleaved (k, p, k, p, ...) so
    that both see the same load: ``(result, wall_k, wall_p, cpu_k, cpu_p)``."""
    tk, tp, ck, cp = [], [], [], []
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        res = kinecal_pipeline(scene, board)
        c1, t1 = time.process_time(), time.perf_counter()
        opencv_plain(scene.images, scene.flange2base, scene.K, scene.dist[:5], board,
                     scene.setup)
        c2, t2 = time.process_time(), time.perf_counter()
        tk.append(t1 - t0)
        tp.append(t2 - t1)
        ck.append(c1 - c0)
        cp.append(c2 - c1)
    return res, min(tk), min(tp), min(ck), min(cp)


def run(setup, kind, n_scenes, n_stations, conditions, seed0=0, repeat=3):
    board = parse_board(BOARDS[kind])
    X = None
    if setup == "eye-to-hand":
        X = look_at([1500.0, 300.0, 1000.0], [500.0, 0.0, 300.0], 0.4)
    rows = ({"kinecal": [], "kinecal refinement on OpenCV's corners": []}
            | {f"OpenCV {m}": [] for m in CV_METHODS})
    corner = {"kinecal": [], "OpenCV": []}
    t_kc, t_cv, c_kc, c_cv = [], [], [], []
    used, flagged, cover = [], 0, []
    for s in range(n_scenes):
        sc = render_handeye_scene(board, K, DIST, SIZE, n_stations, setup=setup, X=X,
                                  conditions=conditions,
                                  vary_light=0.25 if conditions is NOISY else 0.0,
                                  seed=seed0 + s, supersample=2)
        res, tk, tp, ck, cp = timed_pair(sc, board, repeat)
        t_kc.append(tk)
        t_cv.append(tp)
        c_kc.append(ck)
        c_cv.append(cp)
        cv_res, cve, on_cv = opencv_accuracy(sc, board)
        err = pose_error(res.X, sc.X)
        rows["kinecal"].append(err)
        rows["kinecal refinement on OpenCV's corners"].append(on_cv)
        for m, e in cv_res.items():
            rows[f"OpenCV {m}"].append(e)
        corner["kinecal"].append(kinecal_corner_errors(res, sc, board))
        corner["OpenCV"].append(cve)
        used.append(len(res.used))
        flagged += len(res.outliers)
        xt = res.X_std[1]
        dt = res.X[:3, 3] - sc.X[:3, 3]
        cover.append(float(np.sqrt(np.mean((dt / np.maximum(xt, 1e-12)) ** 2))))
    med = {k: np.median(np.array(v), axis=0) for k, v in rows.items()}
    crms = {k: float(np.sqrt(np.mean(np.concatenate(v)))) for k, v in corner.items()}
    ratio = np.array(t_kc) / np.array(t_cv)
    cpu = np.array(c_kc) / np.array(c_cv)
    extra = {"used": (min(used), max(used)), "flagged": flagged,
             "t_kc": float(np.median(t_kc)), "t_cv": float(np.median(t_cv)),
             "ratio": (float(np.median(ratio)), float(ratio.min()), float(ratio.max())),
             "c_kc": float(np.median(c_kc)), "c_cv": float(np.median(c_cv)),
             "cpu_ratio": (float(np.median(cpu)), float(cpu.min()), float(cpu.max())),
             "z_rms": float(np.median(cover))}
    return med, crms, extra


def table(title, med, crms, extra, n_scenes):
    print(f"\n## {title}\n")
    print("| pipeline | median rotation error (deg) | median translation error (mm) |")
    print("|---|---|---|")
    for k, (r, t) in med.items():
        print(f"| {k} | {r:.5f} | {t:.4f} |")
    cv = {k: v for k, v in med.items() if k.startswith("OpenCV")}
    best_r = min(cv.items(), key=lambda kv: kv[1][0])
    best_t = min(cv.items(), key=lambda kv: kv[1][1])
    kr, kt = med["kinecal"]
    print(f"\nkinecal vs the best OpenCV method: rotation {kr:.5f} vs {best_r[1][0]:.5f} deg "
          f"({best_r[0]}): {100 * (1 - kr / best_r[1][0]):.0f} % lower; translation "
          f"{kt:.4f} vs {best_t[1][1]:.4f} mm ({best_t[0]}): "
          f"{100 * (1 - kt / best_t[1][1]):.0f} % lower")
    r = extra["ratio"]
    print(f"corner error against the exact projections (RMS): kinecal {crms['kinecal']:.4f} px, "
          f"OpenCV {crms['OpenCV']:.4f} px; images used per scene {extra['used'][0]}-"
          f"{extra['used'][1]}, stations flagged {extra['flagged']} in {n_scenes} scenes; "
          f"translation error / reported std (median over scenes, RMS of 3 axes) "
          f"{extra['z_rms']:.2f}; time per scene (best of the interleaved repeats, median "
          f"over scenes) kinecal {1e3 * extra['t_kc']:.0f} ms, plain OpenCV pipeline "
          f"{1e3 * extra['t_cv']:.0f} ms: ratio {r[0]:.2f} (scenes {r[1]:.2f}-{r[2]:.2f}); CPU "
          f"time (all threads) kinecal {1e3 * extra['c_kc']:.0f} ms, OpenCV "
          f"{1e3 * extra['c_cv']:.0f} ms: ratio {extra['cpu_ratio'][0]:.2f} (scenes "
          f"{extra['cpu_ratio'][1]:.2f}-{extra['cpu_ratio'][2]:.2f})")


PEER_SCRIPT = """\
import csv, sys
import cv2
import numpy as np
import yaml

images, poses, camera = sys.argv[1:4]
cam = yaml.safe_load(open(camera))
K = np.array(cam["camera_matrix"]["data"], float).reshape(3, 3)
dist = np.array(cam["distortion_coefficients"]["data"], float)
cols, rows, square = {cols}, {rows}, {square}
obj = np.zeros((rows * cols, 3), np.float32)
obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square
crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.001)
R_g, t_g, R_c, t_c = [], [], [], []
for row in csv.DictReader(open(poses)):
    img = cv2.imread(images + "/" + row["image"], cv2.IMREAD_GRAYSCALE)
    ok, c = cv2.findChessboardCorners(img, (cols, rows), flags=cv2.CALIB_CB_ADAPTIVE_THRESH
                                      + cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        continue
    c = cv2.cornerSubPix(img, c, (11, 11), (-1, -1), crit)
    ok, rvec, tvec = cv2.solvePnP(obj, c, K, dist)
    w, x, y, z = (float(row["flange_q" + k]) for k in "wxyz")
    R_g.append(np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]))
    t_g.append(np.array([float(row["flange_" + k]) for k in "xyz"]))
    R_c.append(cv2.Rodrigues(rvec)[0])
    t_c.append(tvec)
R, t = cv2.calibrateHandEye(R_g, t_g, R_c, t_c)
print(np.hstack([R, t]))
"""


def processes(n_stations, repeat):
    """End to end as processes on one written scene (eye-in-hand chessboard): ``kinecal
    handeye-images`` against a plain OpenCV script (its start-up: Python, numpy, OpenCV,
    PyYAML), best of `repeat` interleaved runs each, wall time and CPU time (the child's
    user + system, all threads). Both run from compiled bytecode, as installed code does
    (pip compiles at install): the bytecode goes to a temporary cache
    (``PYTHONPYCACHEPREFIX``) filled by one untimed run of each, whatever
    ``PYTHONDONTWRITEBYTECODE`` says (else kinecal's 70-odd modules would be compiled at every
    start and the peer's one script not)."""
    board = parse_board(BOARDS["chessboard"])
    sc = render_handeye_scene(board, K, DIST, SIZE, n_stations, conditions=NOISY,
                              vary_light=0.25, seed=0, supersample=2)
    with tempfile.TemporaryDirectory() as tmp:
        folder = write_scene(sc, Path(tmp) / "scene")
        script = Path(tmp) / "peer.py"
        script.write_text(PEER_SCRIPT.format(cols=board.cols, rows=board.rows,
                                             square=board.square))
        files = [str(folder / "images"), str(folder / "robot_poses.csv"),
                 str(folder / "camera.yaml")]
        kc = [sys.executable, "-m", "kinecal", "handeye-images", files[0], files[1],
              "--board", BOARDS["chessboard"], "--intrinsics", files[2], "--quiet"]
        peer = [sys.executable, str(script), *files]
        base = [sys.executable, "-c", "import numpy, cv2, yaml"]
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / "pycache")
        cmds = (("kinecal", kc), ("peer", peer), ("import", base))
        for _, cmd in cmds:  # compile once, untimed
            subprocess.run(cmd, check=True, capture_output=True, env=env)
        wall = {name: [] for name, _ in cmds}
        cpu = {name: [] for name, _ in cmds}
        for _ in range(repeat):
            for name, cmd in cmds:
                r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, capture_output=True, env=env)
                wall[name].append(time.perf_counter() - t0)
                r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu[name].append(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
    w = {k: min(v) for k, v in wall.items()}
    c = {k: min(v) for k, v in cpu.items()}
    print(f"\n## End to end as processes ({n_stations} stations, best of {repeat})\n")
    print(f"`kinecal handeye-images` {w['kinecal']:.3f} s, the plain OpenCV script "
          f"{w['peer']:.3f} s: ratio {w['kinecal'] / w['peer']:.2f}; CPU time {c['kinecal']:.3f} "
          f"s against {c['peer']:.3f} s: ratio {c['kinecal'] / c['peer']:.2f}; "
          f"`python -c 'import numpy, cv2, yaml'` {w['import']:.3f} s ({c['import']:.3f} s "
          f"CPU); beyond that start-up: kinecal {w['kinecal'] - w['import']:.3f} s, the "
          f"script {w['peer'] - w['import']:.3f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 scenes of 10 stations")
    ap.add_argument("--scenes", type=int, default=None)
    ap.add_argument("--stations", type=int, default=None)
    ap.add_argument("--clean-scenes", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=None,
                    help="interleaved timing repeats per scene (best kept); default 3, 1 quick")
    ap.add_argument("--timing-only", action="store_true",
                    help="eye-in-hand chessboard scenes and the process comparison only")
    ap.add_argument("--processes-only", action="store_true",
                    help="the process comparison only (best of --repeat, default 5)")
    args = ap.parse_args()
    n = args.scenes or (3 if args.quick else 20)
    m = args.stations or (10 if args.quick else 20)
    nc = args.clean_scenes or (2 if args.quick else 5)
    rep = args.repeat or (1 if args.quick else 3)
    if args.processes_only:
        processes(m, args.repeat or 5)
        return
    print(f"# hand-eye from images: {n} scenes x {m} stations per configuration, "
          f"{SIZE[0]}x{SIZE[1]} px, OpenCV {cv2.__version__}, {cv2.getNumThreads()} OpenCV "
          f"threads, {os.cpu_count()} CPUs")
    t0 = time.perf_counter()
    configs = [("eye-in-hand", "chessboard")] if args.timing_only else \
        [(s, k) for s in ("eye-in-hand", "eye-to-hand") for k in BOARDS]
    for setup, kind in configs:
        med, crms, extra = run(setup, kind, n, m, NOISY,
                               seed0=0 if setup == "eye-in-hand" else 1000, repeat=rep)
        table(f"{setup}, {kind}, blur 0.8 px + noise", med, crms, extra, n)
    if not args.timing_only:
        for setup in ("eye-in-hand", "eye-to-hand"):
            med, crms, extra = run(setup, "chessboard", nc, m, CLEAN,
                                   seed0=100 if setup == "eye-in-hand" else 1100, repeat=rep)
            table(f"{setup}, chessboard, noise-free renders", med, crms, extra, nc)
    processes(m, max(rep, 3))
    print(f"\n(total {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
