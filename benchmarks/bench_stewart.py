"""Stewart-platform CMM (Liu, Liu and Wei 2008): batch Newton FK vs per-row scipy, PSO vs Newton.

Run ``python benchmarks/bench_stewart.py [--quick]``. One core (BLAS threads pinned to 1).
Speeds are printed as ratios against peers timed in the same process:

* batch Newton FK (`StewartPlatform.forward`, vectorized over readings) vs per-row loops of
  ``scipy.optimize.least_squares`` and ``scipy.optimize.fsolve`` (MINPACK hybrd, the
  faster of the two), both with the same neutral start and a residual and analytic
  Jacobian of their own in plain numpy (`plain_residual`: the geometry's numbers, no
  kinecal function inside the solve);
* the paper's PSO (`method="pso"`, Table 1 settings) vs Newton on the Table 3 legs;
* every assembly mode (`forward_all`) on the Table 3 legs.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import fsolve, least_squares  # noqa: E402

from kinecal.kinematics.stewart.platform import StewartPlatform  # noqa: E402

TABLE3_LEGS = np.array([0.750, 0.780, 0.800, 0.900, 0.870, 0.850])


def plain_residual(geom: StewartPlatform):
    """The peer's own residual and Jacobian, plain numpy as a scipy user writes them from
    the paper (eq. 4-5): only the geometry's numbers come from kinecal (joint positions,
    leg offsets), no kinecal function is called inside the solve."""
    base = geom.base_joints.copy()  # (6, 3), base frame
    tip = geom.tip_joints.copy()  # (6, 3), platform frame relative to the probe tip
    off = geom.leg_offsets.copy()

    def rotation(x):
        ca, sa, cb, sb = np.cos(x[3]), np.sin(x[3]), np.cos(x[4]), np.sin(x[4])
        cg, sg = np.cos(x[5]), np.sin(x[5])
        return np.array([[cg * cb, cg * sb * sa - sg * ca, cg * sb * ca + sg * sa],
                         [sg * cb, sg * sb * sa + cg * ca, sg * sb * ca - cg * sa],
                         [-sb, cb * sa, cb * ca]])  # Rz(gamma) Ry(beta) Rx(alpha)

    def residual(x, measured):
        legs = tip @ rotation(x).T + x[:3] - base
        return np.sqrt(np.einsum("ij,ij->i", legs, legs)) - off - measured

    def jac(x, measured):
        R = rotation(x)
        rq = tip @ R.T
        legs = rq + x[:3] - base
        u = legs / np.sqrt(np.einsum("ij,ij->i", legs, legs))[:, None]
        # d|l| / d(x, y, z) = u; by a small rotation w about the tip: (R q) x u . w, and
        # w = E (alpha, beta, gamma)' for the Rz Ry Rx angles
        _, b, g = x[3:]
        E = np.array([[np.cos(g) * np.cos(b), -np.sin(g), 0.0],
                      [np.sin(g) * np.cos(b), np.cos(g), 0.0],
                      [-np.sin(b), 0.0, 1.0]])
        return np.concatenate([u, np.cross(rq, u) @ E], axis=1)

    return residual, jac


def bench_batch(geom: StewartPlatform, n: int, n_peer: int, repeat: int) -> dict:
    poses = geom.random_poses(n, rng=1)
    legs = geom.inverse(poses)
    geom.forward(legs[:100])  # warm-up (imports)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = geom.forward(legs)
        best = min(best, time.perf_counter() - t0)
    ours = n / best
    err_ours = float(np.abs(res.poses[:, :3] - poses[:, :3]).max())

    x0 = geom.neutral_pose()
    residual, jac = plain_residual(geom)
    np.testing.assert_allclose(residual(poses[0], legs[0]), 0.0, atol=1e-12)

    peer_poses = np.empty((n_peer, 6))
    t0 = time.perf_counter()
    for i in range(n_peer):  # the peer: one scipy solve per reading, its own residual
        sol = least_squares(residual, x0, jac=jac, args=(legs[i],), xtol=1e-15, ftol=1e-15)
        peer_poses[i] = sol.x
    peer = n_peer / (time.perf_counter() - t0)
    err_peer = float(np.abs(peer_poses[:, :3] - poses[:n_peer, :3]).max())
    fs_poses = np.empty((n_peer, 6))
    t0 = time.perf_counter()
    for i in range(n_peer):  # the fastest scipy per-row solver: MINPACK hybrd
        fs_poses[i] = fsolve(residual, x0, args=(legs[i],), fprime=jac, xtol=1e-13)
    fs = n_peer / (time.perf_counter() - t0)
    err_fs = float(np.abs(fs_poses[:, :3] - poses[:n_peer, :3]).max())
    return {
        "n": n,
        "ours_per_s": ours,
        "peer_per_s": peer,
        "ratio": ours / peer,
        "fsolve_per_s": fs,
        "fsolve_ratio": ours / fs,
        "fsolve_max_err_m": err_fs,
        "ours_max_err_m": err_ours,
        "peer_max_err_m": err_peer,
        "converged": int(res.converged.sum()),
        "iterations_mean": float(res.iterations.mean()),
    }


def bench_pso(geom: StewartPlatform, seeds: int) -> dict:
    exact = geom.forward(TABLE3_LEGS).poses[0]
    t0 = time.perf_counter()
    for _ in range(200):
        geom.forward(TABLE3_LEGS)
    t_newton = (time.perf_counter() - t0) / 200
    hits, its, secs = 0, [], []
    for s in range(seeds):
        res = geom.forward(TABLE3_LEGS, method="pso", rng=s, on_failure="flag")
        hits += np.linalg.norm(res.poses[0, :3] - exact[:3]) <= 0.5e-6
        its.append(int(res.iterations[0]))
        secs.append(res.elapsed)
    t_pso = float(np.mean(secs))
    return {
        "seeds": seeds,
        "success": int(hits),
        "iterations_median": float(np.median(its)),
        "pso_s": t_pso,
        "newton_s": t_newton,
        "ratio": t_pso / t_newton,
    }


def bench_modes(geom: StewartPlatform, repeat: int) -> dict:
    best, modes = np.inf, None
    for k in range(repeat):
        t0 = time.perf_counter()
        modes = geom.forward_all(TABLE3_LEGS, rng=k)
        best = min(best, time.perf_counter() - t0)
    return {"seconds": best, "modes": len(modes), "above": int(modes.above.sum())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes (seconds)")
    args = ap.parse_args()
    geom = StewartPlatform.liu2008()
    n, n_peer, rep, seeds = (20_000, 100, 2, 10) if args.quick else (100_000, 500, 3, 30)

    b = bench_batch(geom, n, n_peer, rep)
    print(f"batch Newton FK, {b['n']} workspace poses, one core")
    print(f"  kinecal forward (vectorized):   {b['ours_per_s']:12.0f} solves/s  "
          f"max tip error {b['ours_max_err_m']:.1e} m  ({b['converged']}/{b['n']} converged, "
          f"{b['iterations_mean']:.2f} iterations)")  # fmt: skip
    print(f"  scipy least_squares per row:    {b['peer_per_s']:12.0f} solves/s  "
          f"max tip error {b['peer_max_err_m']:.1e} m  ({n_peer} rows)")  # fmt: skip
    print(f"  scipy fsolve per row:           {b['fsolve_per_s']:12.0f} solves/s  "
          f"max tip error {b['fsolve_max_err_m']:.1e} m  ({n_peer} rows)")  # fmt: skip
    print(f"  speed ratio kinecal / least_squares: {b['ratio']:7.0f}x, / fsolve: "
          f"{b['fsolve_ratio']:.0f}x")
    p = bench_pso(geom, seeds)
    print(f"PSO (Liu, Liu and Wei 2008, Table 1) vs Newton on the Table 3 legs, {p['seeds']} seeds")
    print(f"  PSO: {p['success']}/{p['seeds']} within 0.5 um, median {p['iterations_median']:.0f} "
          f"generations, {p['pso_s'] * 1e3:.1f} ms per solve")  # fmt: skip
    print(f"  Newton: {p['newton_s'] * 1e6:.0f} us per solve (single reading)")
    print(f"  time ratio PSO / Newton: {p['ratio']:.0f}x")
    m = bench_modes(geom, rep)
    print(f"forward_all (4096 starts): {m['modes']} modes ({m['above']} above the base) "
          f"in {m['seconds'] * 1e3:.0f} ms")  # fmt: skip


if __name__ == "__main__":
    main()
