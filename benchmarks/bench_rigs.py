"""Camera rigs: accuracy of the three set-ups of docs/rigs.md at 0.3 px corner noise, and
the speed of 100 images from 3 cameras end to end and of the bundle adjustment against a
scipy peer.

Set-ups (`kinecal.vision.rig_scene.render_rig_stations`, default mounts):

- (a) ``head-arm``: a head camera on the 2-joint pan-tilt, a 9x6 chessboard (25 mm) in
  the arm's hand; 100 stations;
- (b) ``kr6-craig``: three static cameras, the board on the flange; 60 stations (~110-175
  images);
- (c) ``kr6-craig``: a stereo pair on the flange, the board on the table; 55 stations.

Each camera 800 x 600 px, f 900 px, barrel distortion; the corners of every board an
image sees whole, projected, plus Gaussian noise of 0.3 px per coordinate; PnP poses from
those corners (`scene_views`). The true model: the nominal plus random errors within the
tolerances (0.5 mm, 0.1 deg) on every calibratable parameter, seeds 0-4; each set-up at
the stations above (~100 images) and at twice as many (~200).

Figures per run:

- mounts against the truth the images can see: the same stations' exact corners
  calibrated (the estimator's noise-free fixed point: the parameters the rig cannot see
  held at nominal, the mounts taking them up) against the noisy calibration, worst mount
  (mm, deg);
- mounts against the truth itself, when the true arm errs only on the parameters the rig
  identifies (the free set of the noise-free fit), worst mount;
- camera-to-camera against the truth (no gauge involved);
- the arm's tool point 150 mm along its flange, after the best rigid alignment at base
  and flange (`aligned_frame_errors`), on 60 held-out stations of the same cell (near the
  calibration) and on 200 random configurations (the workspace): RMS calibrated over
  nominal;
- held-out reprojection (the 60 stations' corners, fresh noise) with the calibrated model
  and mounts over that with the true ones: the reading "within 5 % of the error the true
  model would have".

Speed: (b) rendered with 60 stations (blur 0.8 px, read noise 3), 100 images kept;
`calibrate_rig_images` from the files (detection, intrinsics estimated per camera, PnP,
start, bundle, covariance, words) timed; and the bundle adjustment alone (the stacked
calibration on the rig block, identifiability and covariance included) against scipy
``least_squares`` (``trf``, 2-point Jacobian) on the same unknowns from the same start,
with a vectorised numpy residual a user would write (modified D-H FK, mounts, pinhole
with OpenCV's distortion), no kinecal code inside it.

    python benchmarks/bench_rigs.py [--quick] [--seeds N]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

from bench_arm_camera import craig_fk  # noqa: E402  (the peer's numpy D-H, one copy)
from kinecal import load_model  # noqa: E402
from kinecal.calibration.blocks.api import calibrate_blocks  # noqa: E402
from kinecal.calibration.camera.evaluate import aligned_frame_errors  # noqa: E402
from kinecal.calibration.camera.rig_block import RigBlock  # noqa: E402
from kinecal.calibration.camera.rig_frames import LinkFrames  # noqa: E402
from kinecal.calibration.camera.rig_pixels import Mount, RigPixels  # noqa: E402
from kinecal.calibration.camera.rig_solve import calibrate_rig  # noqa: E402
from kinecal.io.rig_stations import read_rig_stations  # noqa: E402
from kinecal.io.systems import load_machine  # noqa: E402
from kinecal.spatial import (  # noqa: E402
    axis_angle_from_matrix,
    invert_transform,
)
from kinecal.vision.boards import parse_board  # noqa: E402
from kinecal.vision.imaging import ImageConditions  # noqa: E402
from kinecal.vision.rig import parse_rig  # noqa: E402
from kinecal.vision.rig_files import (  # noqa: E402
    write_rig_cameras,
    write_rig_images,
    write_rig_stations_of,
)
from kinecal.vision.rig_images import calibrate_rig_images  # noqa: E402
from kinecal.vision.rig_scene import render_rig_stations, scene_views  # noqa: E402

K = np.array([[900.0, 0.0, 399.5], [0.0, 900.0, 299.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.15, 0.06, 0.0005, -0.0003, 0.0])
SIZE = (800, 600)
BOARD = parse_board("chessboard:9x6:25")
OUT = Path(__file__).parent / "results"


def setup(name):
    """Model, cameras, boards and the chain whose tool point is judged (None: the arm)."""
    if name == "a":
        return load_machine("head-arm"), [Mount("eye", "head")], [Mount("held", "arm")], "arm"
    m = load_model("kr6-craig")
    if name == "b":
        return m, [Mount(f"c{i}", "world") for i in range(3)], [Mount("held", "flange")], None
    return m, [Mount("left", "flange"), Mount("right", "flange")], [Mount("table", "world")], \
        None


def pose_error(A, B):
    D = invert_transform(B) @ A
    return float(np.linalg.norm(D[:3, 3])), float(np.degrees(np.linalg.norm(
        axis_angle_from_matrix(D[:3, :3]))))


def frames(m, tip, q, p):
    if tip is None:
        return m.fk(q, p)
    sm = m.tip_model(tip, p)
    return sm.fk(q[:, [m.joint_names.index(e["name"]) for e in sm.joints]], sm.nominal)


def scene(m, cams, boards, n, seed, errors="random"):
    return render_rig_stations(m, cams, [(b, BOARD) for b in boards], [(K, DIST, SIZE)] *
                               len(cams), n, seed=seed, errors=errors, render=False)


def worst(pairs):
    e = [pose_error(a, b) for a, b in pairs]
    return max(x[0] for x in e), max(x[1] for x in e)


def accuracy(name, n, seed, noise=0.3):
    m, cams, boards, tip = setup(name)
    sc = scene(m, cams, boards, n, seed)
    v, v0 = scene_views(sc, noise, seed), scene_views(sc, 0.0, seed)
    t0 = time.perf_counter()
    r1 = calibrate_rig(m, v, cams, boards, sc.K, sc.dist)
    seconds = time.perf_counter() - t0
    r0 = calibrate_rig(m, v0, cams, boards, sc.K, sc.dist)
    out = {"setup": name, "seed": seed, "stations": n, "images": len(sc.names),
           "bundle_seconds": seconds, "free": len(r1.free)}
    out["mount_vs_seen_mm"], out["mount_vs_seen_deg"] = worst(
        zip(r1.camera_poses + r1.board_poses, r0.camera_poses + r0.board_poses, strict=True))
    out["mount_sigma_mm"] = max(float(np.linalg.norm(s[3:])) for s in
                                r1.camera_sigma + r1.board_sigma)
    if r1.pairs:
        out["pair_mm"], out["pair_deg"] = worst(
            (T, invert_transform(sc.X[a]) @ sc.X[b]) for (a, b), (T, _) in r1.pairs.items())
    # the truth erring only where the rig sees: the mounts against the truth itself
    seen = np.zeros(m.n_params)
    idx = m.index(r0.free)
    seen[idx] = (sc.true_params - m.nominal)[idx]
    sc2 = scene(m, cams, boards, n, seed, seen)
    r2 = calibrate_rig(m, scene_views(sc2, noise, seed), cams, boards, sc2.K, sc2.dist)
    out["mount_raw_mm"], out["mount_raw_deg"] = worst(
        zip(r2.camera_poses + r2.board_poses, sc2.X + sc2.Y, strict=True))
    # held-out: 60 stations of the same cell, and the workspace
    ho = scene(m, cams, boards, 60, seed + 100, sc.true_params - m.nominal)
    truth = sc.true_params
    for what, q in (("near", ho.q), ("workspace", None)):
        if q is None:
            lim = np.asarray(m.joint_limits)
            q = np.random.default_rng(seed).uniform(lim[:, 0], lim[:, 1], (200, m.n_joints))
            q = np.clip(q, -np.radians(170), np.radians(170))
        e0 = aligned_frame_errors(frames(m, tip, q, m.nominal), frames(m, tip, q, truth))
        e1 = aligned_frame_errors(frames(m, tip, q, r1.params), frames(m, tip, q, truth))
        out[f"tool_{what}_nominal_mm"] = float(np.sqrt(np.mean(e0**2)))
        out[f"tool_{what}_calibrated_mm"] = float(np.sqrt(np.mean(e1**2)))
        out[f"tool_{what}_ratio"] = out[f"tool_{what}_calibrated_mm"] / out[
            f"tool_{what}_nominal_mm"]
        out[f"tool_{what}_predicted_mm"] = predicted_tool_rms(m, tip, q, r1)
    vh = scene_views(ho, noise, seed + 200)
    fr = LinkFrames(m, vh.q, [c.link for c in cams + boards])
    z = [0] * len(cams)
    cal = RigPixels(fr, vh, cams, boards, sc.K, sc.dist, r1.camera_poses, r1.board_poses, z)
    tru = RigPixels(fr, vh, cams, boards, sc.K, sc.dist, sc.X, sc.Y, z)
    zero = np.zeros(cal.n_nuisance)
    rc = cal.residuals(r1.params, zero, strict=False)
    rt = tru.residuals(truth, zero, strict=False)
    out["heldout_px_calibrated"] = float(np.sqrt(np.nanmean(rc**2)))
    out["heldout_px_true"] = float(np.sqrt(np.nanmean(rt**2)))
    out["heldout_ratio"] = out["heldout_px_calibrated"] / out["heldout_px_true"]
    return out


def predicted_tool_rms(m, tip, q, res, draws=40):
    """The aligned tool error the fit's covariance predicts (RMS over `draws` parameter
    sets drawn from it): what the calibrated error should be if the estimator reaches the
    information in the pixels."""
    idx = m.index(res.fit.free)
    L = np.linalg.cholesky(res.fit.covariance + 1e-30 * np.eye(len(idx)))
    rng = np.random.default_rng(7)
    ref = frames(m, tip, q, res.params)
    ms = []
    for _ in range(draws):
        p = res.params.copy()
        p[idx] += L @ rng.standard_normal(len(idx))
        ms.append(np.mean(aligned_frame_errors(frames(m, tip, q, p), ref) ** 2))
    return float(np.sqrt(np.mean(ms)))


def rotvecs(w):
    """Rotation matrices ``(n, 3, 3)`` of rotation vectors ``(n, 3)`` (Rodrigues)."""
    th = np.linalg.norm(w, axis=1)[:, None, None]
    k = w / np.where(th[:, :, 0] > 0, th[:, :, 0], 1.0)
    Kx = np.zeros((len(w), 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2], Kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    Kx -= np.swapaxes(Kx, 1, 2)
    return np.eye(3) + np.sin(th) * Kx + (1 - np.cos(th)) * Kx @ Kx


def peer_problem(model, views, free, p0, X0, Y0, Ks, ds):
    """scipy's view of (b): [arm free values, per camera rotvec + t, board rotvec + t]."""
    order = [f"{k}{j + 1}" for j in range(6) for k in ("alpha", "a", "theta", "d")]
    full = model.nominal[model.index(order)]
    where = [order.index(n) for n in free]
    counts = np.array([len(p) for p in views.points])
    img = np.repeat(np.arange(len(counts)), counts)
    P = np.concatenate(views.points)
    cam = views.camera[img]
    obs = np.concatenate(views.pixels)
    k, nc = len(free), len(X0)
    Kc, dc = np.array(Ks), np.array([np.r_[d, np.zeros(8 - len(d))] for d in ds])

    def fun(x):
        p = full.copy()
        p[where] = x[:k]
        F = craig_fk(views.q, p)
        m = x[k:k + 6 * nc].reshape(nc, 6)
        RX, tX = rotvecs(m[:, :3]), m[:, 3:]
        y = x[k + 6 * nc:]
        RY = rotvecs(y[None, :3])[0]
        w = P @ RY.T + y[3:]  # board point on the flange
        u = np.einsum("nij,nj->ni", F[img, :3, :3], w) + F[img, :3, 3]  # world
        pc = np.einsum("nji,nj->ni", RX[cam], u - tX[cam])  # camera
        xn, yn = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
        d = dc[cam]
        r2 = xn * xn + yn * yn
        f = 1 + r2 * (d[:, 0] + r2 * (d[:, 1] + r2 * d[:, 4]))
        xd = xn * f + 2 * d[:, 2] * xn * yn + d[:, 3] * (r2 + 2 * xn * xn)
        yd = yn * f + d[:, 2] * (r2 + 2 * yn * yn) + 2 * d[:, 3] * xn * yn
        Kk = Kc[cam]
        uv = np.column_stack([Kk[:, 0, 0] * xd + Kk[:, 0, 2], Kk[:, 1, 1] * yd + Kk[:, 1, 2]])
        return (uv - obs).ravel()

    x0 = np.concatenate([p0[model.index(free)]]
                        + [np.r_[axis_angle_from_matrix(X[:3, :3]), X[:3, 3]] for X in X0]
                        + [np.r_[axis_angle_from_matrix(Y0[0][:3, :3]), Y0[0][:3, 3]]])
    return fun, x0


def speed(stations, repeats, seed=1):
    m, cams, boards, _ = setup("b")
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        sc = render_rig_stations(m, cams, [(b, BOARD) for b in boards], [(K, DIST, SIZE)] * 3,
                                 stations, seed=seed,
                                 conditions=ImageConditions(blur=0.8, noise=3.0))
        keep = min(100, len(sc.names))
        sc.names, sc.images = sc.names[:keep], sc.images[:keep]
        sc.q, sc.camera, sc.seen = sc.q[:keep], sc.camera[:keep], sc.seen[:keep]
        write_rig_images(sc, d / "images")
        write_rig_stations_of(sc, d / "stations.csv")
        write_rig_cameras(sc, d / "cams")
        rig = parse_rig([f"c{i}:world" for i in range(3)], ["held:flange:chessboard:9x6:25"])
        st = read_rig_stations(d / "stations.csv", m, rig.camera_names, rig.board_names)
        files = [d / "images" / n for n in st.names]
        ends = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = calibrate_rig_images(m, rig, files, st.names, st.camera, st.q, st.board)
            ends.append(time.perf_counter() - t0)
    views = scene_views(sc, 0.3, seed)  # the bundle alone, on the same cell
    block = RigBlock(views, cams, boards, sc.K, sc.dist, [0] * 3)
    nu = block.start(m, m.nominal)
    from kinecal.calibration.blocks.stack import fit_nuisance

    nu, _ = fit_nuisance(block, m, m.nominal, nu)
    X0, Y0, _, _ = block.pixels.unpack(nu)
    ours, fit = [], None
    for _ in range(repeats):
        b = RigBlock(views, cams, boards, sc.K, sc.dist, [0] * 3)
        b.frames = LinkFrames(m, views.q, ["world", "flange"])
        b.set_references(X0, Y0)
        t0 = time.perf_counter()
        fit = calibrate_blocks(m, [b])
        ours.append(time.perf_counter() - t0)
    fun, x0 = peer_problem(m, views, fit.free, m.nominal, X0, Y0, sc.K, sc.dist)
    t0 = time.perf_counter()
    sol = least_squares(fun, x0, method="trf")
    peer = time.perf_counter() - t0
    diff = float(np.abs(sol.x[:len(fit.free)] - fit.params[m.index(fit.free)]).max())
    return {"images": keep, "cameras": 3, "end_to_end_seconds": float(np.median(ends)),
            "end_to_end_runs": ends, "images_used": len(res.names),
            "intrinsics_estimated": True, "bundle_seconds": float(np.median(ours)),
            "scipy_trf_seconds": peer, "scipy_nfev": int(sol.nfev),
            "ratio_scipy_over_kinecal": peer / float(np.median(ours)),
            "max_param_diff": diff}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--no-speed", action="store_true")
    args = ap.parse_args()
    seeds = 1 if args.quick else args.seeds
    counts = {"a": 30, "b": 20, "c": 20} if args.quick else {"a": 100, "b": 60, "c": 55}
    scales = (1,) if args.quick else (1, 2)  # ~100 images, and ~200
    rows = []
    for scale in scales:
        for name in ("a", "b", "c"):
            for seed in range(seeds):
                rows.append(accuracy(name, scale * counts[name], seed))
                print(json.dumps({k: (round(v, 5) if isinstance(v, float) else v)
                                  for k, v in rows[-1].items()}), flush=True)
    if args.no_speed:
        return
    sp = speed(20 if args.quick else 60, 1 if args.quick else 3)
    print(json.dumps(sp))
    if not args.quick:
        OUT.mkdir(exist_ok=True)
        (OUT / "rigs.json").write_text(json.dumps({"accuracy": rows, "speed": sp},
                                                  indent=1) + "\n")


if __name__ == "__main__":
    main()
