"""Forward-kinematics throughput: kinecal's batch FK against a naive loop and roboticstoolbox.

Prints configurations per second and the speed ratios, measured in the same process:

* 10^5 configurations of a 6-axis arm (UR5, standard D-H, tool point);
* a population of 100 parameter vectors x 100 configurations (metaheuristic cost);
* peers: a naive per-configuration numpy loop (4x4 matrices per joint) and
  roboticstoolbox-python's ``DHRobot.fkine`` on the same D-H robot, if installed.

Run: ``python benchmarks/bench_fk.py [--quick]``.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import kinecal


def best_time(fn, repeat=3):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def naive_positions(model, q):
    """One 4x4 product chain per configuration (what a straightforward implementation does)."""
    p = model.nominal
    joints = [(p[model.index([f"theta{i}", f"d{i}", f"a{i}", f"alpha{i}"])]) for i in
              range(1, model.n_joints + 1)]
    tool = np.r_[p[model.index(["tool.x", "tool.y", "tool.z"])], 1.0]
    out = np.empty((q.shape[0], 3))
    for k in range(q.shape[0]):
        T = np.eye(4)
        for i, (th, d, a, al) in enumerate(joints):
            t = th + q[k, i]
            ct, st, ca, sa = np.cos(t), np.sin(t), np.cos(al), np.sin(al)
            A = np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
            T = T @ A
        out[k] = (T @ tool)[:3]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes")
    args = ap.parse_args()
    n = 10_000 if args.quick else 100_000
    n_naive = 500 if args.quick else 3000
    model = kinecal.load_model("ur5")
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (n, 6))

    t_batch = best_time(lambda: model.positions(q))
    t_naive = best_time(lambda: naive_positions(model, q[:n_naive]), repeat=1) * n / n_naive
    np.testing.assert_allclose(naive_positions(model, q[:50]), model.positions(q[:50]),
                               atol=1e-9)
    print(f"positions of {n} configurations (UR5, 6 joints):")
    print(f"  kinecal batch      {t_batch * 1e3:9.1f} ms  {n / t_batch:12.0f} conf/s")
    print(f"  naive numpy loop   {t_naive * 1e3:9.1f} ms  {n / t_naive:12.0f} conf/s"
          f"  (extrapolated from {n_naive})")
    print(f"  ratio kinecal / naive loop: {t_naive / t_batch:.0f}x")

    try:
        import roboticstoolbox as rtb

        p = model.nominal
        links = [rtb.RevoluteDH(d=p[model.index([f"d{i}"])[0]], a=p[model.index([f"a{i}"])[0]],
                                alpha=p[model.index([f"alpha{i}"])[0]],
                                offset=p[model.index([f"theta{i}"])[0]]) for i in range(1, 7)]
        from spatialmath import SE3

        tool = p[model.index(["tool.x", "tool.y", "tool.z"])]
        robot = rtb.DHRobot(links, tool=SE3(*tool))
        m_rtb = min(n, 20_000)
        t_rtb = best_time(lambda: robot.fkine(q[:m_rtb]), repeat=1) * n / m_rtb
        T = robot.fkine(q[:20])
        np.testing.assert_allclose(np.array([t.t for t in T]), model.positions(q[:20]),
                                   atol=1e-6)
        print(f"  roboticstoolbox    {t_rtb * 1e3:9.1f} ms  {n / t_rtb:12.0f} conf/s")
        print(f"  ratio kinecal / roboticstoolbox fkine: {t_rtb / t_batch:.1f}x")
    except ImportError:
        print("  roboticstoolbox-python not installed: peer skipped")

    P, N = 100, 100
    params = model.nominal + rng.normal(0, 1e-3, (P, model.n_params))
    qp = q[:N]
    t_pop = best_time(lambda: model.positions(qp, params))
    t_loop = best_time(lambda: [model.positions(qp, params[k]) for k in range(P)])
    print(f"population {P} parameter vectors x {N} configurations:")
    print(f"  kinecal one call   {t_pop * 1e3:9.2f} ms")
    print(f"  loop over vectors  {t_loop * 1e3:9.2f} ms  ratio {t_loop / t_pop:.1f}x")
    t_jac = best_time(lambda: model.identification_jacobian(q[:1000]))
    print(f"identification Jacobian, 1000 configurations x {model.n_params} parameters: "
          f"{t_jac * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
