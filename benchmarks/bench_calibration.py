"""Calibration speed and accuracy: kinecal's LM with the analytic Jacobian against scipy
``least_squares`` with a finite-difference Jacobian on the same problem (what pybotics does).

Cases:

* ``ur5``: the real laser-tracker data (1000 grid poses; the 20 random poses validate),
  geometric parameters + base frame + tool point, identifiable set;
* ``irb120``: 50 simulated poses, random errors within the paper-002 tolerances, noise
  0.02 mm, 100 validation poses.

Both solvers start from nominal with the same free parameters and residuals; the peer is
timed on the same machine in the same process. Run: ``python benchmarks/bench_calibration.py``.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from scipy.optimize import least_squares

import kinecal
from kinecal.calibration.problem import CalibrationProblem, resolve_free
from kinecal.calibration.serial import CALIBRATION_RANK_TOL
from kinecal.calibration.simulate import simulate
from kinecal.optimize.lsq import levenberg_marquardt


def case_ur5():
    m = kinecal.load_model("ur5")
    return m, kinecal.read_measurements("ur5-laser-tracker:grid", m), kinecal.read_measurements(
        "ur5-laser-tracker:random", m)


def case_irb120():
    m = kinecal.load_model("irb120")
    cal = simulate(m, 50, errors="random", noise=0.02, rng=0)
    val = simulate(m, 100, errors=cal.true_params - m.nominal, noise=0.02, rng=1)
    return m, cal.data, val.data


def run(name, model, data, val, repeat):
    names, _ = resolve_free(model, data, "identifiable", tol=CALIBRATION_RANK_TOL)
    pr = CalibrationProblem(model, data, names)

    def val_mean(x):
        return np.linalg.norm(model.positions(val.q, pr.full(x)) - val.xyz, axis=1).mean()

    def ours():
        return levenberg_marquardt(pr.residuals, pr.jacobian, pr.x0)

    def peer():
        return least_squares(pr.residuals, pr.x0, jac="2-point", method="lm", ftol=1e-15,
                             xtol=1e-15, gtol=1e-15, x_scale="jac")

    def minpack():
        return levenberg_marquardt(pr.residuals, pr.jacobian, pr.x0, solver="minpack")

    t_ours = t_peer = t_mp = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        a = ours()
        t_ours = min(t_ours, time.perf_counter() - t0)
        t0 = time.perf_counter()
        b = peer()
        t_peer = min(t_peer, time.perf_counter() - t0)
        t0 = time.perf_counter()
        c = minpack()
        t_mp = min(t_mp, time.perf_counter() - t0)
    print(f"{name}: {len(data)} poses, {len(names)} free parameters")
    print(f"  kinecal LM, analytic J : {t_ours * 1e3:8.1f} ms, {a.nfev:4d} evaluations, "
          f"cal mean {pr.distances(a.x).mean():.6f}, val mean {val_mean(a.x):.6f}")
    print(f"  scipy LM, 2-point J    : {t_peer * 1e3:8.1f} ms, {b.nfev:4d} evaluations, "
          f"cal mean {pr.distances(b.x).mean():.6f}, val mean {val_mean(b.x):.6f}")
    print(f"  scipy LM, analytic J   : {t_mp * 1e3:8.1f} ms, {c.nfev:4d} evaluations, "
          f"cal mean {pr.distances(c.x).mean():.6f}, val mean {val_mean(c.x):.6f}")
    print(f"  speed ratio vs finite-difference peer: {t_peer / t_ours:.1f}x "
          f"(analytic J alone, MINPACK both: {t_peer / t_mp:.1f}x)")
    return t_peer / t_ours


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one repetition")
    args = ap.parse_args()
    repeat = 1 if args.quick else 3
    for name, make in (("ur5 laser tracker", case_ur5), ("irb120 simulated", case_irb120)):
        run(name, *make(), repeat)


if __name__ == "__main__":
    main()
