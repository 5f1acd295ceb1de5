"""Calibration from ballbars, pairs, fixed points and planes (issue 25): accuracy on hidden
arms, ranks per kind, noise-free recovery, coverage of the 95 % intervals, and speed
against a least-squares sketch with scipy.

Part 1, hidden arms: for each model and seed, an arm with random errors uniform within
the model's tolerances on every calibratable parameter, measured by a ballbar (2 pivots
x 30 rows, 2 um), fixed points (4 x 8 touches, 10 um), planes (2 x 20 touches, 5 um) and
an artifact bar (40 pairs, 2 um); 500 held-out configurations. The mix of the first three
(noise stated, and estimated), then each kind alone: rank, what it cannot see, held-out
tool-point error after the best rigid motion (and similarity: scale free) as a fraction of
the nominal model's.

Part 2, noise-free rows: errors only on the parameters fixed points identify; max
|identified - true| over the free parameters, per kind and for the mix.

Part 3, coverage (Monte Carlo): one hidden IRB-120 (errors on the parameters the mix
identifies), the mix redrawn with new noise ``--draws`` times (touches moved by IK from the
noise-free joints); the share of free parameters whose 95 % interval (1.96 standard
errors) holds the truth, and the spread of the standardised errors.

Part 4, speed: ``calibrate_blocks`` against a plain numpy + scipy sketch of the same
stacked problem: its own vectorised forward kinematics (each D-H / Hayati link one closed-form
``(N, 4, 4)`` array, one product per joint, every row of the three sets in one call), its own
start values, scipy ``least_squares`` with its default 2-point Jacobian (``trf``, and ``lm``
= MINPACK), on the same free parameters; CPU time, best of interleaved rounds; the end
points' held-out errors are compared. (Before 2026-11-28 the peer multiplied five 4 x 4
stacks per joint, built with ``np.tile``; it took 14-27x kinecal's time, a claim a
vectorised residual does not reproduce.)

Run: ``python benchmarks/bench_kinds.py [--quick] [--draws D] [--seeds S]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
from scipy.optimize import least_squares

import kinecal
from kinecal.calibration.blocks.api import calibrate_blocks
from kinecal.calibration.blocks.plan import analyse_kinds
from kinecal.calibration.blocks.simulate import simulate_kind
from kinecal.calibration.diagnostics._common import rigid_rms, similarity_fit
from kinecal.calibration.serial.simulate import random_configurations, random_errors
from kinecal.kinematics.serial.ik import solve_ik

SPEC = {"ballbar": (30, 0.002), "point": (8, 0.010), "plane": (20, 0.005), "pair": (40, 0.002)}
MIX = ("ballbar", "point", "plane")


def simulate_all(m, truth, gen):
    return {k: simulate_kind(m, k, n, true_params=truth, noise=s, rng=gen)
            for k, (n, s) in SPEC.items()}


def held_out(m, truth, params, q):
    Pt = m.positions(q, truth)
    P = m.positions(q, params)
    return rigid_rms(P, Pt), rigid_rms(m.positions(q), Pt), similarity_fit(P, Pt)[1]


# ---------------------------------------------------------------- part 1
def part1(models, seeds):
    print("\n## Part 1: hidden arms (held-out error after rigid alignment / nominal's)\n")
    print("| model | seed | nominal [mm] | mix stated | mix estimated | sigma estimated [um] "
          "| ballbar | pair | point (similarity) | plane (similarity) | ranks b/pr/pt/pl/mix |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in models:
        m = kinecal.load_model(name)
        for seed in seeds:
            gen = np.random.default_rng(seed)
            truth = m.nominal + random_errors(m, gen)
            sims = simulate_all(m, truth, gen)
            q = random_configurations(m, 500, np.random.default_rng(10_000 + seed))
            mix = [sims[k].data for k in MIX]
            stated = calibrate_blocks(m, mix, sigma=[SPEC[k][1] for k in MIX])
            est = calibrate_blocks(m, mix)
            a, nom, _ = held_out(m, truth, stated.params, q)
            b = held_out(m, truth, est.params, q)[0]
            sig = "/".join(f"{1e3 * e['sigma']:.2g}" for e in est.extra["kinds"])
            alone, ranks = {}, []
            for k in ("ballbar", "pair", "point", "plane"):
                r = calibrate_blocks(m, [sims[k].data], sigma=[SPEC[k][1]])
                rig, _, sim = held_out(m, truth, r.params, q)
                alone[k] = rig / nom if k in ("ballbar", "pair") else sim / nom
                ranks.append(str(r.identifiability.rank))
            ranks.append(str(stated.identifiability.rank))
            print(f"| {name} | {seed} | {nom:.3g} | {100 * a / nom:.3f} % | "
                  f"{100 * b / nom:.3f} % | {sig} | {100 * alone['ballbar']:.3f} % | "
                  f"{100 * alone['pair']:.3f} % | {100 * alone['point']:.3f} % | "
                  f"{100 * alone['plane']:.3f} % | {'/'.join(ranks)} |")
        print(f"\n{name}: the mix does not see {stated.extra['not_seen_words']}; points / "
              "planes alone also not the scale\n")


# ---------------------------------------------------------------- part 2
def part2(models):
    print("\n## Part 2: noise-free rows, max |identified - true| on the free parameters\n")
    print("| model | free | ballbar | pair | point | plane | mix |")
    print("|---|---|---|---|---|---|---|")
    for name in models:
        m = kinecal.load_model(name)
        gen = np.random.default_rng(7)
        probe = simulate_kind(m, "point", 8, rng=gen).data
        names = analyse_kinds(m, [probe], "all", tol=1e-4)[0].report.identifiable
        truth = m.nominal + random_errors(m, gen, names)
        sims = {k: simulate_kind(m, k, n, true_params=truth, rng=gen) for k, (n, _) in
                SPEC.items()}
        idx = m.index(names)
        cells = []
        for kinds in (["ballbar"], ["pair"], ["point"], ["plane"], list(MIX)):
            r = calibrate_blocks(m, [sims[k].data for k in kinds], free=names)
            cells.append(f"{np.abs(r.params[idx] - truth[idx]).max():.1e}")
        print(f"| {name} | {len(names)} | " + " | ".join(cells) + " |")


# ---------------------------------------------------------------- part 3
def redraw(m, truth, sims, gen):
    out = []
    for k in MIX:
        sim, s = sims[k], SPEC[k][1]
        d = sim.data
        if k == "ballbar":
            out.append(dataclasses.replace(d, distance=d.distance + gen.normal(0, s, len(d))))
            continue
        P = m.positions(d.q, truth)
        if k == "point":
            T = P + gen.normal(0, s, P.shape)
        else:
            T = P + gen.normal(0, s, len(P))[:, None] * sim.geometry["planes"][d.group, 3:]
        out.append(dataclasses.replace(d, q=solve_ik(m, T, d.q, params=truth, restarts=1,
                                                     rng=gen).q))
    return out


def part3(draws):
    print(f"\n## Part 3: coverage of the 95 % intervals, IRB-120 mix, {draws} draws\n")
    m = kinecal.load_model("irb120")
    gen = np.random.default_rng(11)
    probe = [simulate_kind(m, k, SPEC[k][0], rng=gen).data for k in MIX]
    names = analyse_kinds(m, probe, "all", tol=1e-4)[0].report.identifiable
    truth = m.nominal + random_errors(m, gen, names)
    sims = {k: simulate_kind(m, k, SPEC[k][0], true_params=truth, rng=gen) for k in MIX}
    idx = m.index(names)
    for label, sigma in (("stated", [SPEC[k][1] for k in MIX]), ("estimated", None)):
        z = []
        t0 = time.perf_counter()
        for d in range(draws):
            data = redraw(m, truth, sims, np.random.default_rng([11, d]))
            r = calibrate_blocks(m, data, sigma=sigma, free=names)
            z.append((r.params[idx] - truth[idx]) / r.std[idx])
        z = np.array(z)
        cover = np.mean(np.abs(z) <= 1.96)
        se = np.sqrt(cover * (1 - cover) / z.size)
        per = np.mean(np.abs(z) <= 1.96, axis=0)
        print(f"- noise {label}: coverage {100 * cover:.1f} % (+-{100 * 1.96 * se:.1f} %, "
              f"{len(names)} parameters x {draws} draws), standardised errors: std "
              f"{z.std():.3f}, per-parameter coverage {100 * per.min():.0f}-"
              f"{100 * per.max():.0f} %, {(time.perf_counter() - t0) / draws:.2f} s per draw")


# ---------------------------------------------------------------- part 4: the peer
def link_matrices(th, d, a, al, be):
    """``Rz(th) Tz(d) Tx(a) Rx(al) Ry(be)`` for joint angles `th` ``(N,)`` (the D-H link with
    Hayati's beta), written out as one ``(N, 4, 4)`` array."""
    ct, st = np.cos(th), np.sin(th)
    ca, sa, cb, sb = np.cos(al), np.sin(al), np.cos(be), np.sin(be)
    A = np.zeros((len(th), 4, 4))
    A[:, 0, 0] = ct * cb - st * sa * sb
    A[:, 0, 1] = -st * ca
    A[:, 0, 2] = ct * sb + st * sa * cb
    A[:, 0, 3] = a * ct
    A[:, 1, 0] = st * cb + ct * sa * sb
    A[:, 1, 1] = ct * ca
    A[:, 1, 2] = st * sb - ct * sa * cb
    A[:, 1, 3] = a * st
    A[:, 2, 0] = -ca * sb
    A[:, 2, 1] = sa
    A[:, 2, 2] = ca * cb
    A[:, 2, 3] = d
    A[:, 3, 3] = 1.0
    return A


def sketch_positions(geo, q):
    """Tool points ``(N, 3)`` of a D-H / Hayati arm without base or tool frame (the IRB-120
    file): the product of the links' matrices, all configurations at once."""
    T = None
    for j in range(q.shape[1]):
        th, d, a, al, be = geo[j]
        A = link_matrices(q[:, j] + th, d, a, al, be)
        T = A if T is None else T @ A
    return T[:, :3, 3]


def part4(rounds: int):
    print(f"\n## Part 4: speed against a numpy + scipy sketch (IRB-120 mix, best of {rounds} "
          "interleaved rounds)\n")
    m = kinecal.load_model("irb120")
    gen = np.random.default_rng(3)
    truth = m.nominal + random_errors(m, gen)
    sims = simulate_all(m, truth, gen)
    data = [sims[k].data for k in MIX]
    sigma = [SPEC[k][1] for k in MIX]
    q_val = random_configurations(m, 500, np.random.default_rng(99))
    res = calibrate_blocks(m, data, sigma=sigma)
    names = res.free
    cols = {"theta": 0, "d": 1, "a": 2, "alpha": 3, "beta": 4}
    digits = "0123456789"
    pick = [(int(n[len(n.rstrip(digits)):]) - 1, cols[n.rstrip(digits)]) for n in names]
    rows_, cols_ = np.array([j for j, _ in pick]), np.array([c for _, c in pick])
    nom = np.zeros((6, 5))
    for j, e in enumerate(m.joints):
        nom[j] = [e.get("theta", 0), e.get("d", 0), e.get("a", 0), e.get("alpha", 0),
                  e.get("beta", 0)]  # the model's joints, in rad
    bb, pt, pl = data
    q_all = np.concatenate([bb.q, pt.q, pl.q])  # one forward kinematics for every row
    n1, n2 = len(bb.q), len(bb.q) + len(pt.q)
    assert np.allclose(sketch_positions(nom, q_all), m.positions(q_all), atol=1e-9)
    gb, gp, gl = bb.group, pt.group, pl.group
    k = len(pick)

    def residual(x):
        geo = nom.copy()
        geo[rows_, cols_] = x[:k]
        v = x[k:]
        P = sketch_positions(geo, q_all)
        P1, P2, P3 = P[:n1], P[n1:n2], P[n2:]
        c = v[:6].reshape(2, 3)
        r1 = (np.linalg.norm(P1 - c[gb], axis=1) - bb.distance) / sigma[0]
        s_ = v[6:18].reshape(4, 3)
        r2 = ((P2 - s_[gp]) / sigma[1]).ravel()
        w = v[18:].reshape(2, 3)  # each plane's normal as polar angles, and its offset
        nrm = np.column_stack([np.sin(w[:, 0]) * np.cos(w[:, 1]),
                               np.sin(w[:, 0]) * np.sin(w[:, 1]), np.cos(w[:, 0])])
        r3 = (np.einsum("ij,ij->i", nrm[gl], P3) - w[gl, 2]) / sigma[2]
        return np.concatenate([r1, r2, r3])

    def start():
        P = sketch_positions(nom, q_all)
        P1, P2, P3 = P[:n1], P[n1:n2], P[n2:]
        v = []
        for g in range(2):  # pivots: linear sphere fit with the radii known
            X = P1[gb == g]
            A = np.column_stack([2 * X, -np.ones(len(X))])
            b = (X**2).sum(1) - bb.distance[gb == g] ** 2
            v.append(np.linalg.lstsq(A, b, rcond=None)[0][:3])
        v += [P2[gp == g].mean(0) for g in range(4)]
        for g in range(2):
            X = P3[gl == g]
            n = np.linalg.svd(X - X.mean(0))[2][-1]
            v.append([np.arccos(np.clip(n[2], -1, 1)), np.arctan2(n[1], n[0]),
                      n @ X.mean(0)])
        return np.r_[nom[rows_, cols_], np.concatenate(v)]

    def peer(method):
        return least_squares(residual, start(), method=method, jac="2-point")

    fns = {"kinecal": lambda: calibrate_blocks(m, data, sigma=sigma),
           "trf": lambda: peer("trf"), "lm": lambda: peer("lm")}
    best = dict.fromkeys(fns, np.inf)
    out = {}
    for _ in range(rounds):  # interleaved: every solver sees the same load
        for name, fn in fns.items():
            t0 = time.process_time()
            out[name] = fn()
            best[name] = min(best[name], time.process_time() - t0)
    mine = held_out(m, truth, res.params, q_val)
    print("| solver | CPU time [s] | evaluations | held-out rigid [mm] | time / kinecal's |")
    print("|---|---|---|---|---|")
    print(f"| kinecal calibrate_blocks (LM, analytic Jacobian, everything) | "
          f"{best['kinecal']:.3f} | {res.evaluations} | {mine[0]:.4g} | 1 |")
    for method in ("trf", "lm"):
        sol = out[method]
        p = m.nominal.copy()
        p[m.index(names)] = sol.x[:k]
        err = held_out(m, truth, p, q_val)[0]
        jac = f" + {sol.njev} Jacobians" if sol.njev else ""
        print(f"| scipy least_squares {method}, 2-point, vectorised numpy FK | "
              f"{best[method]:.3f} | {sol.nfev}{jac} | {err:.4g} | "
              f"{best[method] / best['kinecal']:.2f}x |")
    print(f"\nnominal held-out error {mine[1]:.4g} mm; {len(names)} arm parameters, 24 "
          "unknowns of the gauges; the peer's residual, one call: "
          f"{_one_call(residual, start()) * 1e6:.0f} us")


def _one_call(fn, x, rounds: int = 200) -> float:
    """CPU seconds of one call of `fn(x)` (best of `rounds`)."""
    best = np.inf
    for _ in range(rounds):
        t0 = time.process_time()
        fn(x)
        best = min(best, time.process_time() - t0)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--draws", type=int, default=None)
    ap.add_argument("--seeds", type=int, default=None)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    seeds = range(args.seeds or (2 if args.quick else 5))
    part1(["irb120"] if args.quick else ["irb120", "ur5", "kr6-craig"], seeds)
    part2(["irb120"] if args.quick else ["irb120", "ur5", "kr6-craig"])
    part3(args.draws or (20 if args.quick else 200))
    part4(3 if args.quick else 5)


if __name__ == "__main__":
    main()
