"""Forward-kinematics throughput: kinecal's chunked batch FK against roboticstoolbox's C
path, the numpy tangent floor and a naive loop, at 10^3 .. 10^6 configurations; and one
configuration at a time against a hand-written numpy D-H product.

Peers, measured in the same process on the same joint angles, rounds interleaved, best
of each:

* roboticstoolbox-python ``rtb.models.DH.UR5().ets().eval(q)`` with all configurations
  in one ``(N, 6)`` array: its fastest batch path (the C ``ETS_fkine`` loops over the
  rows; ``ets().fkine(q)`` wraps the same loop in SE3 objects, and ``eval`` per row costs
  a Python call each -- both are timed once at 10^4 to show it);
* the floor: ``np.tan(q)`` of the same ``(N, 6)`` angles, one vectorised transcendental
  per joint angle, the least any numpy FK that evaluates each joint's rotation must spend
  (kinecal's kernels take one tangent of the half angle per joint; ``np.sin(q)`` and
  ``np.cos(q)`` are printed beside it: numpy evaluates the float64 sine and cosine element
  by element, many times the tangent's cost, so they are no floor);
* a naive per-configuration loop of 4x4 matrix products (extrapolated from a sample);
* one configuration per call (a controller asking for one pose): ``model.fk(q)`` with
  ``q`` of shape ``(6,)`` against roboticstoolbox's ``ets().eval(q)`` of one configuration
  (its C code) and a hand-written numpy product of six D-H matrices, as a user writes it
  (``np.cos`` / ``np.sin`` and ``np.array`` per joint) and tightened (``math.cos`` /
  ``math.sin``, the alpha terms precomputed).

Times are CPU times (``process_time``) of interleaved rounds, best of each: the machine is
shared and the other jobs' load moves wall times far more.

kinecal runs the same D-H robot (roboticstoolbox's UR5 parameters in mm, no tool):
``positions`` (tool point only) and ``fk`` (4x4 poses, like ``eval``). Also a population
(100 parameter vectors x 100 configurations, one call against a loop over the vectors)
and the identification Jacobian.

Run: ``python benchmarks/bench_fk.py [--quick]``.
"""

from __future__ import annotations

import argparse
import math
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import kinecal
from kinecal.kinematics.serial.model import SerialModel


def rtb_ur5():
    import roboticstoolbox as rtb

    return rtb.models.DH.UR5()


def kinecal_twin(robot) -> SerialModel:
    """The roboticstoolbox UR5's D-H parameters as a kinecal model (mm)."""
    joints = [dict(theta=L.offset, d=1e3 * L.d, a=1e3 * L.a, alpha=L.alpha)
              for L in robot.links]
    return SerialModel("ur5-rtb", "dh", joints)


def naive_positions(model, q):
    """One 4x4 product chain per configuration (what a straightforward implementation does)."""
    p = model.nominal
    joints = [(p[model.index([f"theta{i}", f"d{i}", f"a{i}", f"alpha{i}"])]) for i in
              range(1, model.n_joints + 1)]
    out = np.empty((q.shape[0], 3))
    for k in range(q.shape[0]):
        T = np.eye(4)
        for i, (th, d, a, al) in enumerate(joints):
            t = th + q[k, i]
            ct, st, ca, sa = np.cos(t), np.sin(t), np.cos(al), np.sin(al)
            A = np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                          [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
            T = T @ A
        out[k] = T[:3, 3]
    return out


def dh_product(model):
    """Hand-written one-configuration D-H forward kinematics of `model` (no base or tool):
    as a user writes it, and tightened; both return the 4x4 tool frame."""
    p = model.nominal
    joints = [tuple(p[model.index([f"theta{i}", f"d{i}", f"a{i}", f"alpha{i}"])])
              for i in range(1, model.n_joints + 1)]
    tight = [(th, d, a, math.cos(al), math.sin(al)) for th, d, a, al in joints]

    def plain(q):
        T = np.eye(4)
        for (th, d, a, al), qi in zip(joints, q, strict=True):
            ct, st, ca, sa = np.cos(th + qi), np.sin(th + qi), np.cos(al), np.sin(al)
            T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                              [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
        return T

    def tightened(q):
        T = np.eye(4)
        for (th, d, a, ca, sa), qi in zip(tight, q, strict=True):
            ct, st = math.cos(th + qi), math.sin(th + qi)
            T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                              [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
        return T

    return plain, tightened


def one_at_a_time(model, ets, q: np.ndarray, rounds: int) -> None:
    """`model.fk` of one configuration per call against roboticstoolbox's C ``eval`` of one
    configuration and the hand-written D-H products; CPU time (``process_time``)."""
    plain, tightened = dh_product(model)
    for k in range(20):
        np.testing.assert_allclose(model.fk(q[k])[0], plain(q[k]), atol=1e-9)
        np.testing.assert_allclose(model.fk(q[k])[0, :3, :3], ets.eval(q[k])[:3, :3],
                                   atol=1e-12)
    m = len(q)
    t = interleaved({"fk": lambda: [model.fk(r) for r in q],
                     "rtb": lambda: [ets.eval(r) for r in q],
                     "plain": lambda: [plain(r) for r in q],
                     "tight": lambda: [tightened(r) for r in q]}, rounds, time.process_time)
    us = {k: v / m * 1e6 for k, v in t.items()}
    print(f"one configuration per call ({m} calls, CPU, best of {rounds} interleaved rounds): "
          f"kinecal fk {us['fk']:.2f} us, roboticstoolbox ets().eval {us['rtb']:.2f} us "
          f"(kinecal / rtb {t['fk'] / t['rtb']:.2f}x), hand-written numpy D-H product "
          f"{us['plain']:.1f} us (tightened: {us['tight']:.1f} us); kinecal / hand-written "
          f"{t['fk'] / t['plain']:.2f}x, / tightened {t['fk'] / t['tight']:.2f}x")


def interleaved(fns: dict, rounds: int, clock=time.perf_counter) -> dict:
    """Best time of each function over `rounds` interleaved rounds (`clock`: wall time, or
    ``time.process_time`` for CPU time)."""
    best = dict.fromkeys(fns, np.inf)
    for _ in range(rounds):
        for name, fn in fns.items():
            t0 = clock()
            fn()
            best[name] = min(best[name], clock() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="sizes up to 10^5, fewer rounds")
    args = ap.parse_args()
    sizes = [1_000, 10_000, 100_000] if args.quick else [1_000, 10_000, 100_000, 1_000_000]
    robot = rtb_ur5()
    ets = robot.ets()
    model = kinecal_twin(robot)
    rng = np.random.default_rng(0)
    q_all = rng.uniform(-np.pi, np.pi, (sizes[-1], 6))
    # the same robot: kinecal (mm) against roboticstoolbox (m)
    T_rtb = ets.eval(q_all[:200])
    np.testing.assert_allclose(model.fk(q_all[:200])[:, :3, :3], T_rtb[:, :3, :3], atol=1e-12)
    np.testing.assert_allclose(model.positions(q_all[:200]), 1e3 * T_rtb[:, :3, 3], atol=1e-9)

    one_at_a_time(model, ets, q_all[:2000], 3 if args.quick else 7)
    print("UR5 forward kinematics, ns per configuration (CPU time, best of interleaved rounds)")
    print(f"{'N':>9} {'positions':>10} {'fk 4x4':>8} {'rtb eval':>9} {'tan':>8} {'sin+cos':>8} "
          f"{'rtb/pos':>8} {'rtb/fk':>7} {'pos/floor':>9} {'fk/floor':>8}")
    for n in sizes:
        q = q_all[:n]
        rounds = 2 if n >= 1_000_000 else (3 if args.quick else 5)
        t = interleaved({
            "positions": lambda q=q: model.positions(q),
            "fk": lambda q=q: model.fk(q),
            "rtb": lambda q=q: ets.eval(q),
            "floor": lambda q=q: np.tan(q),
            "sincos": lambda q=q: (np.sin(q), np.cos(q)),
        }, rounds, time.process_time)
        ns = {k: v / n * 1e9 for k, v in t.items()}
        print(f"{n:>9} {ns['positions']:>10.0f} {ns['fk']:>8.0f} {ns['rtb']:>9.0f} "
              f"{ns['floor']:>8.0f} {ns['sincos']:>8.0f} {t['rtb'] / t['positions']:>7.2f}x "
              f"{t['rtb'] / t['fk']:>6.2f}x {t['positions'] / t['floor']:>8.2f}x "
              f"{t['fk'] / t['floor']:>7.2f}x")

    n = 10_000
    q = q_all[:n]
    t_fkine = interleaved({"fkine": lambda: ets.fkine(q)}, 2)["fkine"]
    m = 2000
    t_loop = interleaved({"loop": lambda: [ets.eval(row) for row in q[:m]]}, 2)["loop"]
    t_naive = interleaved({"naive": lambda: naive_positions(model, q[:500])}, 1)["naive"]
    np.testing.assert_allclose(naive_positions(model, q[:50]), model.positions(q[:50]),
                               atol=1e-9)
    print(f"other paths at {n}: rtb ets().fkine {t_fkine / n * 1e9:.0f} ns, "
          f"ets().eval per row {t_loop / m * 1e9:.0f} ns, naive numpy loop "
          f"{t_naive / 500 * 1e9:.0f} ns per configuration")

    ur5 = kinecal.load_model("ur5")
    P, N = 100, 100
    params = ur5.nominal + rng.normal(0, 1e-3, (P, ur5.n_params))
    qp = q_all[:N]
    t = interleaved({"pop": lambda: ur5.positions(qp, params),
                     "loop": lambda: [ur5.positions(qp, params[k]) for k in range(P)]},
                    3 if args.quick else 7)
    print(f"population {P} parameter vectors x {N} configurations: one call "
          f"{t['pop'] * 1e3:.2f} ms, loop over vectors {t['loop'] * 1e3:.2f} ms, "
          f"ratio {t['loop'] / t['pop']:.1f}x")
    for n in (1_000, 100_000):
        t = interleaved({"jac": lambda n=n: ur5.identification_jacobian(q_all[:n])}, 3)["jac"]
        print(f"identification Jacobian, {n} configurations x {ur5.n_params} parameters: "
              f"{t * 1e3:.2f} ms ({t / n * 1e9:.0f} ns per configuration)")


if __name__ == "__main__":
    main()
