"""Calibration speed and accuracy against scipy, and kinecal.calibrate() from 10^3 to 10^6
poses (time per pose, peak memory, overhead over the raw solver).

Part 1, real and small problems (best of 3, same process): kinecal's LM with the
analytic Jacobian against scipy ``least_squares`` with a finite-difference Jacobian
(what pybotics does) and with kinecal's analytic Jacobian (MINPACK), on

* ``ur5``: the real laser-tracker data (1000 grid poses; the 20 random poses validate);
* ``irb120``: 50 simulated poses, random errors, noise 0.02 mm, 100 validation poses.

Part 2, scaling: ``kinecal.calibrate(ur5, data)`` on 10^3, 10^4, 10^5 and 10^6 simulated
UR5 poses (random errors within the tolerances, noise 0.01 mm), each size in a fresh
process that loads the data from a ``.npz`` file and warms up on 10^4 of its poses, so
that the peak resident memory (``VmHWM``) measured around the call is the call's own.
Beside it, in the same process: the raw solver (`levenberg_marquardt` on the problem
with calibrate's final free parameters, from nominal: the same end point, without the
identifiability analysis, the growth step, the covariance and the statistics) and the
same solver on the first (nominal) identifiable set.

Part 3, at 10^5 poses (10^4 with ``--quick``): calibrate() against scipy
``least_squares`` with default settings (``trf``, 2-point Jacobian) and with kinecal's
analytic Jacobian (``trf``, and ``lm`` = MINPACK, scipy's fastest here) on the same
residual function, free parameters and start; the end points are compared.

Run: ``python benchmarks/bench_calibration.py [--quick] [--repeat R]``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from scipy.optimize import least_squares

import kinecal
from kinecal.calibration.serial.api import CALIBRATION_RANK_TOL
from kinecal.calibration.serial.problem import CalibrationProblem, resolve_free
from kinecal.calibration.serial.simulate import simulate
from kinecal.data import Measurements
from kinecal.optimize.lsq import levenberg_marquardt


# ---------------------------------------------------------------- part 1
def case_ur5():
    m = kinecal.load_model("ur5")
    return m, kinecal.read_measurements("ur5-laser-tracker:grid", m), kinecal.read_measurements(
        "ur5-laser-tracker:random", m)


def case_irb120():
    m = kinecal.load_model("irb120")
    cal = simulate(m, 50, errors="random", noise=0.02, rng=0)
    val = simulate(m, 100, errors=cal.true_params - m.nominal, noise=0.02, rng=1)
    return m, cal.data, val.data


def run_small(name, model, data, val, repeat):
    names, _ = resolve_free(model, data, "identifiable", tol=CALIBRATION_RANK_TOL)
    pr = CalibrationProblem(model, data, names)

    def val_mean(x):
        return np.linalg.norm(model.positions(val.q, pr.full(x)) - val.xyz, axis=1).mean()

    def ours():
        return levenberg_marquardt(pr.residuals, pr.jacobian, pr.x0,
                                   normal_equations=pr.normal_equations)

    def peer():
        return least_squares(pr.residuals, pr.x0, jac="2-point", method="lm", ftol=1e-15,
                             xtol=1e-15, gtol=1e-15, x_scale="jac")

    def minpack():
        return levenberg_marquardt(pr.residuals, pr.jacobian, pr.x0, solver="minpack")

    t = dict.fromkeys(("ours", "peer", "minpack"), np.inf)
    out = {}
    ours(), minpack()  # warm-up: first calls (LAPACK, caches) are not timed
    for _ in range(repeat):
        for key, fn in (("ours", ours), ("peer", peer), ("minpack", minpack)):
            t0 = time.perf_counter()
            out[key] = fn()
            t[key] = min(t[key], time.perf_counter() - t0)
    a, b, c = out["ours"], out["peer"], out["minpack"]
    print(f"{name}: {len(data)} poses, {len(names)} free parameters")
    for label, key, r in (("kinecal LM, analytic J ", "ours", a),
                          ("scipy LM, 2-point J    ", "peer", b),
                          ("scipy LM, analytic J   ", "minpack", c)):
        print(f"  {label}: {t[key] * 1e3:8.1f} ms, {r.nfev:4d} evaluations, "
              f"cal mean {pr.distances(r.x).mean():.6f}, val mean {val_mean(r.x):.6f}")
    print(f"  speed ratio vs finite-difference peer: {t['peer'] / t['ours']:.1f}x "
          f"(vs MINPACK with the analytic J: {t['minpack'] / t['ours']:.1f}x)")


# ---------------------------------------------------------------- part 2 (child processes)
def _status_bytes(field: str) -> int | None:
    """``VmHWM`` (peak resident set, reset by exec unlike getrusage's ru_maxrss, which a
    child inherits from its parent) or ``VmRSS`` from /proc/self/status, in bytes."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def _peak_bytes() -> int:
    peak = _status_bytes("VmHWM")
    return peak if peak is not None else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _rss_bytes() -> int:
    return _status_bytes("VmRSS") or 0


def child_make(n: int, path: str) -> None:
    m = kinecal.load_model("ur5")
    sim = simulate(m, n, errors="random", noise=0.01, rng=0)
    np.savez(path, q=sim.data.q, xyz=sim.data.xyz)


def _lm(pr):
    t0 = time.perf_counter()
    r = levenberg_marquardt(pr.residuals, pr.jacobian, pr.x0,
                            normal_equations=pr.normal_equations)
    return time.perf_counter() - t0, r


def child_scaling(path: str, raw: bool) -> None:
    """calibrate() on the saved data: time, peak memory above the loaded data; then the
    raw solver on the final and on the first free set. Below 10^6 poses the three are
    timed in interleaved rounds (5 up to 10^4 poses, 2 at 10^5) and the best of each kept:
    small runs are at the mercy of the machine's other jobs."""
    m = kinecal.load_model("ur5")
    d = np.load(path)
    data = Measurements(d["q"], d["xyz"])
    n = len(data)
    w = min(n, 10_000)  # warm-up (imports, LAPACK, caches) on the same kind of data
    kinecal.calibrate(m, Measurements(d["q"][:w], d["xyz"][:w]))
    base = max(_peak_bytes(), _rss_bytes())
    rounds = 5 if n <= 10_000 else (2 if n < 1_000_000 else 1)
    first = resolve_free(m, Measurements(d["q"][:20000], d["xyz"][:20000]),
                         "identifiable", tol=CALIBRATION_RANK_TOL)[0]
    best = {"calibrate": np.inf, "final": np.inf, "first": np.inf}
    out: dict = {"n": n}
    for k in range(rounds):
        t0 = time.perf_counter()
        res = kinecal.calibrate(m, data)
        best["calibrate"] = min(best["calibrate"], time.perf_counter() - t0)
        if k == 0:
            out.update(peak_increase_bytes=_peak_bytes() - base, evaluations=res.evaluations,
                       free=len(res.free), cost=float(res.history[-1]))
        if raw:
            pr = CalibrationProblem(m, data, res.free)
            t, r = _lm(pr)
            best["final"] = min(best["final"], t)
            out["raw_final_nfev"] = int(r.nfev)
            out["raw_final_dx"] = float(np.abs(r.x - res.params[pr.index]).max())
            t, r = _lm(CalibrationProblem(m, data, first))
            best["first"] = min(best["first"], t)
            out["raw_first_nfev"] = int(r.nfev)
    out["calibrate_s"] = best["calibrate"]
    if raw:
        out["raw_final_s"], out["raw_first_s"] = best["final"], best["first"]
    print(json.dumps(out))


def child_scipy(path: str, rounds: int) -> None:
    """calibrate() against scipy least_squares on the same problem, same process, rounds
    interleaved (the best time of each is kept)."""
    m = kinecal.load_model("ur5")
    d = np.load(path)
    data = Measurements(d["q"], d["xyz"])
    kinecal.calibrate(m, Measurements(d["q"][:10_000], d["xyz"][:10_000]))
    res = kinecal.calibrate(m, data)
    pr = CalibrationProblem(m, data, res.free)
    x_ref = res.params[pr.index]
    cost_ref = 0.5 * float(np.sum(pr.residuals(x_ref) ** 2))
    peers = {
        "trf_2point": dict(),  # scipy's defaults: trf, 2-point Jacobian, ftol 1e-8
        "trf_analytic": dict(jac=pr.jacobian),
        "lm_analytic": dict(jac=pr.jacobian, method="lm"),
    }
    best = dict.fromkeys(["calibrate", *peers], np.inf)
    out = {"n": len(data), "free": len(res.free), "cost": cost_ref}
    for _ in range(rounds):
        t0 = time.perf_counter()
        kinecal.calibrate(m, data)
        best["calibrate"] = min(best["calibrate"], time.perf_counter() - t0)
        for key, kw in peers.items():
            t0 = time.perf_counter()
            s = least_squares(pr.residuals, pr.x0, **kw)
            best[key] = min(best[key], time.perf_counter() - t0)
            out[key] = {"nfev": int(s.nfev), "cost_rel": float(s.cost / cost_ref - 1.0),
                        "dx_over_std": float(np.max(np.abs(s.x - x_ref) / res.std[pr.index]))}
    out["calibrate_s"] = best["calibrate"]
    for key in peers:
        out[key]["s"] = best[key]
    print(json.dumps(out))


def _child(*args: str) -> dict | None:
    cmd = [sys.executable, __file__, "--child", *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1]) if lines else None


def _span(values, fmt="{:.2f}") -> str:
    lo, hi = min(values), max(values)
    return fmt.format(lo) if fmt.format(lo) == fmt.format(hi) else \
        f"{fmt.format(lo)}-{fmt.format(hi)}"


def run_scaling(sizes, repeat: int, scipy_n: int) -> None:
    with tempfile.TemporaryDirectory(prefix="kinecal-bench-") as tmp:
        files = {}
        for n in sorted(set(sizes) | {scipy_n}):
            files[n] = str(Path(tmp) / f"ur5-{n}.npz")
            _child("make", str(n), files[n])
        print(f"calibrate() on simulated UR5 poses, {repeat} fresh processes per size "
              "(ranges; each the best of its rounds)")
        print(f"{'poses':>9} {'calibrate s':>14} {'us/pose':>12} {'peak B/pose':>12} "
              f"{'/ raw (final set)':>18} {'/ raw (first set)':>18} {'evals cal/raw':>14}")
        rows = {}
        for n in sizes:
            runs = [_child("scaling", files[n], "raw") for _ in range(repeat)]
            rows[n] = runs
            print(f"{n:>9} {_span([r['calibrate_s'] for r in runs], '{:.3f}'):>14} "
                  f"{_span([r['calibrate_s'] / n * 1e6 for r in runs]):>12} "
                  f"{_span([r['peak_increase_bytes'] / n for r in runs], '{:.0f}'):>12} "
                  f"{_span([r['calibrate_s'] / r['raw_final_s'] for r in runs]):>18} "
                  f"{_span([r['calibrate_s'] / r['raw_first_s'] for r in runs]):>18} "
                  f"{runs[0]['evaluations']:>6}/{runs[0]['raw_final_nfev']}")
        big = [n for n in sizes if n >= 10_000]
        if len(big) > 1:
            per = {n: [r["calibrate_s"] / n for r in rows[n]] for n in big}
            best = [min(v) for v in per.values()]
            worst = max(max(v) for v in per.values()) / min(min(v) for v in per.values())
            print(f"  time per pose over {big[0]}..{big[-1]}, largest / smallest: "
                  f"{max(best) / min(best):.2f}x (best run of each size), {worst:.2f}x (any "
                  "runs)")
        print(f"  same end point: raw solver on the final set ends within "
              f"{max(r['raw_final_dx'] for rs in rows.values() for r in rs):.1e} of calibrate")
        print(f"calibrate() vs scipy least_squares at {scipy_n} poses (same residuals, free "
              "set and start)")
        for _ in range(max(1, repeat - 1)):
            s = _child("scipy", files[scipy_n], "2")
            print(f"  calibrate {s['calibrate_s']:.2f} s ({s['free']} free; best of 2 rounds "
                  "interleaved with the peers)")
            for key, label in (("trf_2point", "defaults (trf, 2-point J)"),
                               ("trf_analytic", "trf, kinecal's analytic J"),
                               ("lm_analytic", "lm (MINPACK), kinecal's analytic J")):
                p = s[key]
                print(f"  scipy {label:<36} {p['s']:7.2f} s, {p['nfev']:3d} evaluations, "
                      f"ratio {p['s'] / s['calibrate_s']:5.1f}x; end point: cost "
                      f"{p['cost_rel']:+.1e} relative, {p['dx_over_std']:.1e} std")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, one repetition")
    ap.add_argument("--repeat", type=int, default=None, help="runs per size (default 3)")
    ap.add_argument("--only", choices=("small", "scaling"), default=None)
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        kind, *rest = args.child
        {"make": lambda: child_make(int(rest[0]), rest[1]),
         "scaling": lambda: child_scaling(rest[0], raw=len(rest) > 1),
         "scipy": lambda: child_scipy(rest[0], int(rest[1]))}[kind]()
        return
    repeat = args.repeat or (1 if args.quick else 3)
    if args.only in (None, "small"):
        for name, make in (("ur5 laser tracker", case_ur5), ("irb120 simulated", case_irb120)):
            run_small(name, *make(), repeat)
    if args.only in (None, "scaling"):
        sizes = [1_000, 10_000] if args.quick else [1_000, 10_000, 100_000, 1_000_000]
        run_scaling(sizes, repeat, 10_000 if args.quick else 100_000)


if __name__ == "__main__":
    main()
