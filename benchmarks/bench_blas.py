"""BLAS threads under load: ``kinecal.calibrate()`` at 10^5 simulated UR5 poses with numpy's
default BLAS threads, on a quiet and on a loaded machine.

The calibration runs in a fresh interpreter whose BLAS libraries load with their default
thread count (numpy's and scipy's OpenBLAS: one thread per core), as in a user's Python
session. In that process, rounds interleaved, best and median of each:

* ``kinecal``: ``kinecal.calibrate(model, data)`` as a user calls it (kinecal chooses the
  threads of its products: one, `kinecal._blas`);
* ``one thread`` (the reference): the same call inside the user's own
  ``threadpoolctl.threadpool_limits(1)`` -- what a user who knows the trap writes;
* ``libraries' default``: the same call with ``KINECAL_BLAS_THREADS=0`` (kinecal leaves
  the libraries' threads alone: what every call did before kinecal chose them).

"Loaded" starts one busy process (a Python ``while True`` loop) per core beside the
calibration, as other jobs on a shared machine do, and stops them after.

Run: ``python benchmarks/bench_blas.py [--quick] [--poses N] [--rounds R]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

CHILD = r"""
import json, os, sys, time
import numpy as np
import scipy.linalg  # noqa: F401  (scipy's own OpenBLAS loaded before the first call)
from threadpoolctl import threadpool_info, threadpool_limits
import kinecal
from kinecal.calibration.serial.simulate import simulate

n, rounds = int(sys.argv[1]), int(sys.argv[2])
model = kinecal.load_model("ur5")
data = simulate(model, n, errors="random", noise=0.01, rng=1).data
threads = sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

def run_kinecal():
    os.environ.pop("KINECAL_BLAS_THREADS", None)
    return kinecal.calibrate(model, data)

def run_one_thread():
    os.environ["KINECAL_BLAS_THREADS"] = "0"
    with threadpool_limits(1):
        return kinecal.calibrate(model, data)

def run_default():
    os.environ["KINECAL_BLAS_THREADS"] = "0"
    return kinecal.calibrate(model, data)

fns = {"kinecal": run_kinecal, "one thread": run_one_thread, "libraries' default": run_default}
kinecal.calibrate(model, data.subset(np.arange(2000)))  # warm-up
times = {k: [] for k in fns}
params = {}
for _ in range(rounds):
    for name, fn in fns.items():
        t0 = time.perf_counter()
        res = fn()
        times[name].append(time.perf_counter() - t0)
        params[name] = res.params
same = all(np.array_equal(params["kinecal"], p) for p in params.values())
print(json.dumps({"threads": threads, "times": times, "same": bool(same)}))
"""


def busy(count: int) -> list[subprocess.Popen]:
    """`count` processes that keep one core busy each."""
    return [subprocess.Popen([sys.executable, "-c", "while True:\n    pass"])
            for _ in range(count)]


def run(n: int, rounds: int, load: int) -> None:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                        "KINECAL_BLAS_THREADS")}
    load_before = os.getloadavg()[0]
    hogs = busy(load)
    try:
        out = subprocess.run([sys.executable, "-c", CHILD, str(n), str(rounds)], env=env,
                             capture_output=True, text=True, check=True)
    finally:
        for p in hogs:
            p.kill()
            p.wait()
    res = json.loads(out.stdout.strip().splitlines()[-1])
    t = res["times"]
    ref_min, ref_med = min(t["one thread"]), statistics.median(t["one thread"])
    label = f"{load} busy processes" if load else "no added load"
    print(f"\ncalibrate(), {n} UR5 poses, {label}, load average before "
          f"{load_before:.1f}; BLAS threads at load {res['threads']}; "
          f"{rounds} interleaved rounds; same parameters in every mode: {res['same']}")
    print("| mode | min [s] | median [s] | / one thread (min) | / one thread (median) |")
    print("|---|---|---|---|---|")
    for name, v in t.items():
        print(f"| {name} | {min(v):.3f} | {statistics.median(v):.3f} | "
              f"{min(v) / ref_min:.2f}x | {statistics.median(v) / ref_med:.2f}x |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 x 10^4 poses, 2 rounds")
    ap.add_argument("--poses", type=int, default=None)
    ap.add_argument("--rounds", type=int, default=None)
    args = ap.parse_args()
    n = args.poses or (20_000 if args.quick else 100_000)
    rounds = args.rounds or (2 if args.quick else 3)
    cores = os.cpu_count() or 1
    run(n, rounds, 0)
    run(n, rounds, cores)


if __name__ == "__main__":
    main()
