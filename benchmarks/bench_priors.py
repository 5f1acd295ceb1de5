"""Priors for small data sets (`--prior`): held-out error, the choice of ``auto``, coverage.

Studies (simulated arms with a hidden truth: every calibratable parameter uniform within
the model's tolerances, the motion-capture set-up of a real small set: a base (tracker)
frame to identify and three markers on the flange):

* ``small``: 25-40 poses, noise 0.5-2 mm per coordinate, four bundled arms (IRB-120,
  UR5, PUMA 560, KR6 Craig), 31-33 free parameters (the default identifiable set): held-out
  mean error (500 random poses of the true arm, every marker, noise-free) of the fit
  without a prior, with a fixed ridge (``--prior`` at the model's tolerances, and at a
  quarter of them), and with ``--prior auto``; the same on the arms without markers with
  ``--free all`` (31-33 free, several of them unidentifiable);
* ``large``: 1000 poses: what ``auto`` chooses and its held-out error against no prior;
* ``coverage``: how often the 95 % intervals (+-1.96 standard errors) of ``auto``'s fit
  cover the true parameters, Monte Carlo over the small sets (target 90-97 %).

Run: ``python benchmarks/bench_priors.py [--quick]``; results in
``benchmarks/results/priors.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import kinecal
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.calibration.serial.simulate import random_configurations, random_errors, simulate
from kinecal.kinematics.serial.markers import with_markers
from kinecal.optimize.lsq import levenberg_marquardt

ARMS = ("irb120", "ur5", "puma560", "kr6-craig")
#: the tracker's frame in the robot's: 1.5 m away, turned 30 deg (nominal; the truth is
#: within the tolerances of it)
BASE = [1500.0, -300.0, 200.0, 0.0, 0.0, np.radians(30.0)]
MARKERS = {"A": [60.0, 0.0, 30.0], "B": [-30.0, 52.0, 30.0], "C": [-30.0, -52.0, 30.0]}


def setup(name: str, markers: bool) -> kinecal.SerialModel:
    """A bundled arm with a base frame to identify (and three markers)."""
    m = kinecal.load_model(name)
    m = dataclasses.replace(m, base=list(BASE), joint_limits=np.array(m.joint_limits),
                            tolerances=dict(m.tolerances),
                            fixed=tuple(f for f in m.fixed if not f.startswith("base.")))
    return with_markers(m, MARKERS) if markers else m


def held_out(model, params, truth, q, marker) -> float:
    """Mean distance between the calibrated and the true arm's points (length unit)."""
    return float(np.linalg.norm(model.positions(q, params, marker)
                                - model.positions(q, truth, marker), axis=1).mean())


def equivalent_truth(m, truth: np.ndarray, free: list[str]) -> np.ndarray:
    """The values the free parameters take on dense noise-free data of the true arm, the
    others held at nominal (what a calibration can recover: a held parameter's error goes
    into the free ones it is confounded with); a free set the data cannot separate keeps
    the truth's own values (the fit starts there and nothing moves it)."""
    q = random_configurations(m, 3000, np.random.default_rng(77))
    mk = np.arange(3000) % len(m.marker_names) if m.marker_names else None
    dense = kinecal.Measurements(q=q, xyz=m.positions(q, truth, mk), marker=mk,
                                 marker_names=tuple(m.marker_names))
    prob = CalibrationProblem(m, dense, free)
    res = levenberg_marquardt(prob.residuals, prob.jacobian, truth[prob.index],
                              normal_equations=prob.normal_equations)
    return prob.full(res.x)


def trial(name: str, markers: bool, n: int, noise: float, seed: int, free: str,
          variants: dict) -> dict:
    m = setup(name, markers)
    gen = np.random.default_rng(seed)
    err = random_errors(m, gen)
    sim = simulate(m, n, errors=err, noise=noise, rng=gen)
    qv = random_configurations(m, 500, np.random.default_rng(10_000 + seed))
    mv = np.arange(500) % len(m.marker_names) if markers else None
    truth = m.nominal + err
    out = {}
    eq = {}
    for label, prior in variants.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = kinecal.calibrate(m, sim.data, free=free, prior=prior)
        key = tuple(res.free)
        if key not in eq:
            eq[key] = equivalent_truth(m, truth, res.free)
        idx = m.index(res.free)
        z = np.abs(res.params[idx] - eq[key][idx]) / res.std[idx]
        entry = res.extra.get("prior") or {}
        out[label] = {"held_out": held_out(m, res.params, truth, qv, mv),
                      "free": len(res.free), "covered": int((z <= 1.96).sum()),
                      "counted": int(np.isfinite(z).sum()),
                      "chosen": entry.get("used"), "strength": entry.get("strength")}
    return out


def variants(m) -> dict:
    tol = m.tolerances
    ang = np.degrees(tol["angle"]) if m.angle_unit == "deg" else tol["angle"]
    return {"none": None,
            "ridge 1 tol": f"lengths={tol['length']},angles={ang}",
            "ridge 1/4 tol": f"lengths={tol['length'] / 4},angles={ang / 4}",
            "auto": "auto"}


def study_small(seeds: int) -> tuple[list[str], list[dict]]:
    rows, all_trials = [], []
    lines = ["## Small sets: held-out mean error [mm] (mean over trials +- its standard error)",
             "", "auto - better: auto's mean minus the better mean of no prior and the ridge at "
             "the tolerances (negative: auto is better); paired over the trials.", "",
             "| arm | set-up | free | trials | no prior | ridge 1 tol | ridge 1/4 tol | "
             "auto | auto - better | auto's choice (none / prior) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for markers, free in ((True, "identifiable"), (False, "all")):
        for name in ARMS:
            m = setup(name, markers)
            res = []
            for seed in range(seeds):
                gen = np.random.default_rng(seed)
                n = int(gen.integers(25, 41))
                noise = float(gen.choice([0.5, 1.0, 2.0]))
                t = trial(name, markers, n, noise, 1000 * seed + 7, free, variants(m))
                res.append(t)
                all_trials.append({"arm": name, "markers": markers, "n": n, "noise": noise,
                                   **t})
            labels = list(variants(m))
            H = np.array([[r[k]["held_out"] for k in labels] for r in res])
            mean, se = H.mean(axis=0), H.std(axis=0, ddof=1) / np.sqrt(len(res))
            better = 0 if mean[0] <= mean[1] else 1
            d = H[:, 3] - H[:, better]
            none_chosen = sum(r["auto"]["chosen"] == "none" for r in res)
            cells = " | ".join(f"{a:.3f} +- {b:.3f}" for a, b in zip(mean, se, strict=True))
            setup_text = "base + 3 markers" if markers else "base, 1 tool point"
            lines.append(f"| {name} | {setup_text} | {res[0]['none']['free']} | {len(res)} | "
                         f"{cells} | {d.mean():+.3f} +- {d.std(ddof=1) / np.sqrt(len(d)):.3f}"
                         f" | {none_chosen} / {len(res) - none_chosen} |")
            rows.append(H)
        H = np.vstack(rows[-len(ARMS):])
        better = 0 if H[:, 0].mean() <= H[:, 1].mean() else 1
        d = H[:, 3] - H[:, better]
        lines.append(f"| all four | {'base + 3 markers' if markers else 'base, 1 tool point'} "
                     f"| | {len(H)} | " + " | ".join(f"{v:.3f}" for v in H.mean(axis=0))
                     + f" | {d.mean():+.3f} +- {d.std(ddof=1) / np.sqrt(len(d)):.3f} | |")
    return lines, all_trials


def coverage_lines(trials: list[dict]) -> list[str]:
    lines = ["", "## Coverage of the 95 % intervals (+-1.96 standard errors), all free "
             "parameters of the small-set trials", "",
             "| fit | parameters counted | covered |", "|---|---|---|"]
    for label in ("none", "ridge 1 tol", "auto"):
        for markers in (True, False):
            sel = [t for t in trials if t["markers"] == markers]
            c = sum(t[label]["covered"] for t in sel)
            k = sum(t[label]["counted"] for t in sel)
            setup_text = "base + 3 markers" if markers else "base, 1 tool point, --free all"
            lines.append(f"| {label} ({setup_text}) | {k} | {100.0 * c / max(k, 1):.1f} % |")
    return lines


def study_large(seeds: int, n: int) -> list[str]:
    lines = ["", f"## Large sets ({n} poses x 3 markers, noise 1 mm): auto against no prior",
             "", "| arm | runs | auto chose no prior | held-out no prior [mm] | "
             "held-out auto [mm] | largest difference [mm] | time auto / none |",
             "|---|---|---|---|---|---|---|"]
    for name in ARMS:
        m = setup(name, True)
        diffs, none_n, h0, h1, ratios = [], 0, [], [], []
        for seed in range(seeds):
            gen = np.random.default_rng(500 + seed)
            err = random_errors(m, gen)
            sim = simulate(m, n, errors=err, noise=1.0, rng=gen)
            qv = random_configurations(m, 500, np.random.default_rng(20_000 + seed))
            mv = np.arange(500) % 3
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t0 = time.perf_counter()
                r0 = kinecal.calibrate(m, sim.data)
                t1 = time.perf_counter()
                r1 = kinecal.calibrate(m, sim.data, prior="auto")
                t2 = time.perf_counter()
            truth = m.nominal + err
            a, b = held_out(m, r0.params, truth, qv, mv), held_out(m, r1.params, truth, qv, mv)
            h0.append(a)
            h1.append(b)
            diffs.append(abs(a - b))
            none_n += r1.extra["prior"]["used"] == "none"
            ratios.append((t2 - t1) / (t1 - t0))
        lines.append(f"| {name} | {seeds} | {none_n} | {np.mean(h0):.4f} | {np.mean(h1):.4f} "
                     f"| {max(diffs):.2g} | {np.median(ratios):.1f}x |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results",
                                                  "priors.md"))
    args = ap.parse_args()
    seeds = 4 if args.quick else 25
    t0 = time.perf_counter()
    lines = ["# Priors for small data sets (`bench_priors.py`)", ""]
    small, trials = study_small(seeds)
    lines += small
    lines += coverage_lines(trials)
    lines += study_large(1 if args.quick else 5, 300 if args.quick else 1000)
    lines += ["", f"({time.perf_counter() - t0:.0f} s)"]
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.quick:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text)


if __name__ == "__main__":
    main()
