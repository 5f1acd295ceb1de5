"""Calibrations beyond their poses: held-out error where the joints leave the calibrated range.

Studies:

* ``ur10``: the IPA UR10 data set (``ur10-ipa``; series A and B bundled, C and D read from
  their upstream exports when given with ``--series C=FILE D=FILE``). Calibrate on one
  series (T-Mac positions only, model ``ur10-tmac.yaml``), then *re-register* the base
  frame and the tool point on the held-out series with the arm held fixed (each series is
  its own tracker set-up; kinecal's ``--validate-register all``,
  `kinecal.calibration.serial.validation_frame.apply_validation_register`), and report the
  held-out mean distance error. Every fixed error model and
  ``auto``; each twice: with its terms held at the edges of the calibrated joint range
  (kinecal) and, for comparison, free (the same fit evaluated with an envelope of a
  million turns: terms as fitted, anywhere).
* ``ur5``: the bundled UR5 laser-tracker data, grid -> random (inside the range).
* ``half``: synthetic UR5 arms calibrated over q1 < 0 and validated over q1 >= 0 (300 +
  300 poses, noise 0.02 mm): truths whose joint errors the candidate terms do not
  contain (harmonics of order 5 and 6), and truths they do.

Run: ``python benchmarks/bench_extrapolation.py [--quick] [--series C=FILE D=FILE]``;
results in ``benchmarks/results/extrapolation.md``.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import os
import time
import warnings
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import kinecal
from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.calibration.serial.validation_frame import apply_validation_register
from kinecal.diagnostics import KinecalWarning
from kinecal.io.ipa_export import convert_ipa_export
from kinecal.kinematics.serial.joint_errors import JointErrors
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope

RESULTS = Path(__file__).parent / "results" / "extrapolation.md"
#: fixed error models compared with auto (family, harmonic order)
FIXED = [("harmonic", 1), ("harmonic", 2), ("harmonic", 3), ("harmonic", 4), ("scale", None),
         ("compliance", None), ("full", 2)]


def ur10_model() -> kinecal.SerialModel:
    from kinecal.datasets import bundled_csv

    return kinecal.load_model(bundled_csv("ur10-ipa:model"))


def reregistered(res, held, free: bool = False) -> float:
    """Held-out mean distance error of calibration `res` after re-registering base and tool
    on all of `held` with the arm held (kinecal's ``--validate-register all``); `free`: the
    same fit with its terms free beyond the calibrated range."""
    r = copy.copy(res)
    r.extra = dict(res.extra)
    if free:
        r.nominal_model = free_terms(res.nominal_model)
    apply_validation_register(r, held, "all", 1.0, None)
    return float(np.mean(r.val_after))


def free_terms(model):
    """The same fitted model with its terms applied anywhere (an envelope of a million
    turns about the same middle: nothing held, the anchor unchanged)."""
    je = model.joint_errors
    if je is None or je.envelope is None:
        return model
    env = je.envelope
    mid = 0.5 * (np.asarray(env.low) + np.asarray(env.high))
    wide = JointEnvelope(tuple(mid - 2e6 * np.pi), tuple(mid + 2e6 * np.pi), env.revolute)
    return dataclasses.replace(model, joint_errors=je.within(wide))


def series(extra: dict[str, Path]) -> dict[str, kinecal.Measurements]:
    m = ur10_model()
    out = {s: kinecal.read_measurements(f"ur10-ipa:{s}", m) for s in "AB"}
    for name, path in extra.items():
        converted = Path(os.environ.get("TMPDIR", "/tmp")) / f"ur10-ipa-{name}.csv"
        convert_ipa_export(path, converted)
        out[name] = kinecal.read_measurements(converted, m)
    return out


def study_ur10(data: dict, splits: list[tuple[str, str]], fixed: list) -> list[str]:
    m = ur10_model()
    lines = ["## UR10 (ur10-ipa): calibrate on one series, re-register base and tool on "
             "another", "",
             "Held-out mean distance error [mm] after the re-registration; in brackets the "
             "same fit with its terms free beyond the calibrated range.", "",
             "| split | geometric | auto (choice) | auto vs geometric | "
             + " | ".join(f"{f}{h or ''}" for f, h in fixed) + " |",
             "|---|---|---|---|" + "---|" * len(fixed)]
    for cal, held in splits:
        geo = kinecal.calibrate(m, data[cal])
        g = reregistered(geo, data[held])
        t = time.perf_counter()
        auto = kinecal.calibrate_error_model(m, data[cal], "auto")
        seconds = time.perf_counter() - t
        a, a_free = reregistered(auto, data[held]), reregistered(auto, data[held], True)
        cells = []
        for fam, h in fixed:
            r = kinecal.calibrate_error_model(m, data[cal], fam, harmonics=h)
            cells.append(f"{reregistered(r, data[held]):.3f} "
                         f"({reregistered(r, data[held], True):.3f})")
        lines.append(f"| {cal} -> {held} | {g:.3f} | {a:.3f} ({a_free:.3f}), "
                     f"{auto.extra['error_model']['selected']}, {seconds:.0f} s | "
                     f"{100 * (a / g - 1):+.1f} % | " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    return lines + [""]


def study_ur5() -> list[str]:
    m = kinecal.load_model("ur5")
    cal = kinecal.read_measurements("ur5-laser-tracker:grid", m)
    val = kinecal.read_measurements("ur5-laser-tracker:random", m)
    geo = kinecal.calibrate(m, cal, validate=val)
    auto = kinecal.calibrate_error_model(m, cal, "auto", validate=val)
    line = (f"| UR5 grid -> random | {geo.val_after.mean():.4f} | {auto.val_after.mean():.4f}"
            f" | {auto.extra['error_model']['selected']} |")
    print(line, flush=True)
    return ["## UR5 (ur5-laser-tracker), inside the calibrated range", "",
            "| split | geometric [mm] | auto [mm] | auto's choice |", "|---|---|---|---|",
            line, ""]


#: synthetic truths of the half-range study: (label, terms, coefficient values)
HALF_TRUTHS = [
    ("order-5 harmonic on q1 (not a candidate)",
     JointErrors(harmonics=5, harmonic_joints=(1, 2)), {"dq1.sin5": 3e-4, "dq2.cos1": 2e-4}),
    ("order-6/5 harmonics on q2, q3",
     JointErrors(harmonics=6, harmonic_joints=(2, 3)),
     {"dq2.sin6": 4e-4, "dq3.cos5": 3e-4, "dq2.cos1": 2e-4}),
    ("first harmonics on q1..q3", JointErrors(harmonics=1, harmonic_joints=(1, 2, 3)),
     {"dq1.sin1": 2e-4, "dq2.cos1": 3e-4, "dq3.sin1": -2e-4}),
    ("q1 scale, q2 harmonic", JointErrors(harmonics=1, harmonic_joints=(2,), scale=(1,)),
     {"dq1.scale": 1e-4, "dq2.cos1": 2e-4}),
    ("geometric only", None, {}),
]


def half_range(spec, values, seed: int, n: int = 300) -> tuple[float, float, str]:
    """Geometric and auto validation means of a UR5 calibrated over q1 < 0, validated over
    q1 >= 0 (the truth: random geometry and the joint errors `values` of `spec`)."""
    ur5 = kinecal.load_model("ur5")
    rng = np.random.default_rng(seed)
    q = random_configurations(ur5, 2 * n, rng)
    q[:, 0] = rng.uniform(-np.pi, np.pi, 2 * n)
    cal_i, val_i = np.flatnonzero(q[:, 0] < 0)[:n], np.flatnonzero(q[:, 0] >= 0)[:n]
    model = dataclasses.replace(ur5, joint_errors=spec)
    e = np.zeros(model.n_params)
    e[:ur5.n_params] = simulate(ur5, 1, errors="random", rng=seed).true_params - ur5.nominal
    for name, v in values.items():
        e[model.index([name])[0]] = v
    sim = simulate(model, 2 * n, errors=e, noise=0.02, q=q, rng=seed)
    cal, val = sim.data.subset(cal_i), sim.data.subset(val_i)
    geo = kinecal.calibrate(ur5, cal, validate=val)
    auto = kinecal.calibrate_error_model(ur5, cal, "auto", validate=val)
    return (float(geo.val_after.mean()), float(auto.val_after.mean()),
            auto.extra["error_model"]["selected"])


def study_half(seeds: list[int]) -> list[str]:
    lines = ["## Synthetic UR5: calibrated over q1 < 0, validated over q1 >= 0", "",
             "| truth | seed | geometric [mm] | auto [mm] | auto vs geometric | choice |",
             "|---|---|---|---|---|---|"]
    for label, spec, values in HALF_TRUTHS:
        for seed in seeds:
            g, a, sel = half_range(spec, values, seed)
            lines.append(f"| {label} | {seed} | {g:.4f} | {a:.4f} | {100 * (a / g - 1):+.1f} % "
                         f"| {sel} |")
            print(lines[-1], flush=True)
    return lines + [""]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="A -> B and B -> A only, auto "
                    "and two fixed models, one seed")
    ap.add_argument("--series", nargs="*", default=[], metavar="NAME=FILE",
                    help="upstream exports of further series (C, D) to hold out")
    args = ap.parse_args()
    warnings.simplefilter("ignore", KinecalWarning)
    extra = dict(s.split("=", 1) for s in args.series)
    data = series({k: Path(v) for k, v in extra.items()})
    names = ["A", "B", *extra]
    splits = [(a, b) for a in "AB" for b in names if a != b]
    fixed = FIXED[1:3] if args.quick else FIXED
    lines = ["# Beyond the calibrated poses", "",
             f"`python benchmarks/bench_extrapolation.py{' --quick' if args.quick else ''}"
             f"{' --series ...' if extra else ''}`, {time.strftime('%Y-%m-%d')}.", ""]
    lines += study_ur10(data, splits if not args.quick else [("A", "B"), ("B", "A")], fixed)
    lines += study_ur5()
    lines += study_half([1] if args.quick else [1, 2, 3])
    if not args.quick:
        RESULTS.write_text("\n".join(lines) + "\n")
        print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
