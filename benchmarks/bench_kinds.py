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
stacked problem (its own forward kinematics of the D-H / Hayati chain, its own start
values, scipy ``least_squares`` with its default 2-point Jacobian and with ``lm``), on the
same free parameters, best of 3; the end points' held-out errors are compared.

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
def _rot(axis, c, s):
    n = c.shape
    R = np.zeros(n + (4, 4))
    R[..., 3, 3] = 1.0
    i, j = [(1, 2), (0, 2), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s if axis != 1 else s
    R[..., j, i] = s if axis != 1 else -s
    return R


def _trans(v, n):
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = v
    return T


class Sketch:
    """A plain numpy forward kinematics of a D-H / Hayati arm without base or tool frame
    (the IRB-120 file), and the stacked residual of ballbar, point and plane rows."""

    def positions(self, geo, q):
        n = len(q)
        T = np.tile(np.eye(4), (n, 1, 1))
        for j in range(q.shape[1]):
            th, d, a, al, be = geo[j]
            ang = q[:, j] + th
            T = (T @ _rot(2, np.cos(ang), np.sin(ang)) @ _trans([0, 0, d], n)
                 @ _trans([a, 0, 0], n) @ _rot(0, np.full(n, np.cos(al)), np.full(n, np.sin(al)))
                 @ _rot(1, np.full(n, np.cos(be)), np.full(n, np.sin(be))))
        return T[:, :3, 3]


def part4():
    print("\n## Part 4: speed against a numpy + scipy sketch (IRB-120 mix, best of 3)\n")
    m = kinecal.load_model("irb120")
    gen = np.random.default_rng(3)
    truth = m.nominal + random_errors(m, gen)
    sims = simulate_all(m, truth, gen)
    data = [sims[k].data for k in MIX]
    sigma = [SPEC[k][1] for k in MIX]
    q_val = random_configurations(m, 500, np.random.default_rng(99))
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        res = calibrate_blocks(m, data, sigma=sigma)
        best = min(best, time.perf_counter() - t0)
    names = res.free
    cols = {"theta": 0, "d": 1, "a": 2, "alpha": 3, "beta": 4}
    digits = "0123456789"
    pick = [(int(n[len(n.rstrip(digits)):]) - 1, cols[n.rstrip(digits)]) for n in names]
    nom = np.zeros((6, 5))
    for j, e in enumerate(m.joints):
        nom[j] = [e.get("theta", 0), e.get("d", 0), e.get("a", 0), e.get("alpha", 0),
                  e.get("beta", 0)]  # the model's joints, in rad
    sketch = Sketch()
    bb, pt, pl = data
    qs = [bb.q, pt.q, pl.q]
    assert np.allclose(sketch.positions(nom, qs[0]), m.positions(qs[0]), atol=1e-9)

    def unpack(x):
        geo = nom.copy()
        for (j, c), v in zip(pick, x[:len(pick)], strict=True):
            geo[j, c] = v
        return geo, x[len(pick):]

    gb, gp, gl = bb.group, pt.group, pl.group

    def residual(x):
        geo, v = unpack(x)
        P1, P2, P3 = (sketch.positions(geo, q) for q in qs)
        c = v[:6].reshape(2, 3)
        r1 = (np.linalg.norm(P1 - c[gb], axis=1) - bb.distance) / sigma[0]
        s = v[6:18].reshape(4, 3)
        r2 = ((P2 - s[gp]) / sigma[1]).ravel()
        pl_v = v[18:].reshape(2, 3)  # normal's polar angles and offset
        nrm = np.column_stack([np.sin(pl_v[:, 0]) * np.cos(pl_v[:, 1]),
                               np.sin(pl_v[:, 0]) * np.sin(pl_v[:, 1]), np.cos(pl_v[:, 0])])
        r3 = (np.einsum("ij,ij->i", nrm[gl], P3) - pl_v[gl, 2]) / sigma[2]
        return np.concatenate([r1, r2, r3])

    def start():
        P1, P2, P3 = (sketch.positions(nom, q) for q in qs)
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
        x0 = np.r_[[nom[j, c] for j, c in pick], np.concatenate(v)]
        return x0

    out = {}
    for method, jac in (("trf", "2-point"), ("lm", "2-point")):
        t_best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            sol = least_squares(residual, start(), method=method, jac=jac)
            t_best = min(t_best, time.perf_counter() - t0)
        geo, _ = unpack(sol.x)
        p = m.nominal.copy()
        for (j, c), n in zip(pick, names, strict=True):
            p[m.index([n])[0]] = geo[j, c]
        out[method] = (t_best, sol.nfev, held_out(m, truth, p, q_val)[0])
    mine = held_out(m, truth, res.params, q_val)
    print("| solver | time [s] | evaluations | held-out rigid [mm] | ratio to kinecal |")
    print("|---|---|---|---|---|")
    print(f"| kinecal calibrate_blocks (LM, analytic Jacobian, everything) | {best:.3f} | "
          f"{res.evaluations} | {mine[0]:.4g} | 1 |")
    for method, (t, nfev, err) in out.items():
        print(f"| scipy least_squares {method}, 2-point, numpy FK | {t:.3f} | {nfev} | "
              f"{err:.4g} | {t / best:.2f}x |")
    print(f"\nnominal held-out error {mine[1]:.4g} mm; {len(names)} arm parameters, 24 "
          "unknowns of the gauges")


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
    part4()


if __name__ == "__main__":
    main()
