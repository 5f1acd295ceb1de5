"""Command-line start-up and end-to-end throughput, timed as subprocesses.

Each command runs `--repeat` times, interleaved with its reference, and the minimum and
median wall times are printed (the machine is shared: the minimum is the least disturbed
run, the median the typical one):

* ``kinecal --help`` against ``python -c "import numpy"``;
* ``kinecal calibrate ur5 ur5-laser-tracker:grid --validate ur5-laser-tracker:random``
  against ``python -c "import numpy, scipy.linalg"``;
* ``kinecal stewart fk liu2008-cmm LEGS.csv`` on 10^5 leg readings (the CSV written
  first, from random workspace poses) against the API's throughput: the same solve,
  ``StewartPlatform.forward`` on the in-memory readings, timed in this process.

``kinecal`` is run as ``python -m kinecal`` with this interpreter (what the console script
does: import ``kinecal.cli`` and call ``main``).

Run: ``python benchmarks/bench_cli.py [--quick] [--repeat R]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

KINECAL = [sys.executable, "-m", "kinecal"]


def wall(cmd: list[str], stdout=subprocess.DEVNULL) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, stdout=stdout, stderr=subprocess.DEVNULL, check=True)
    return time.perf_counter() - t0


def compare(label: str, cmd: list[str], ref_label: str, ref: list[str], repeat: int) -> None:
    wall(cmd), wall(ref)  # warm the file cache
    t, r = [], []
    for _ in range(repeat):
        t.append(wall(cmd))
        r.append(wall(ref))
    print(f"{label}: min {min(t):.3f} s, median {statistics.median(t):.3f} s")
    print(f"  {ref_label}: min {min(r):.3f} s, median {statistics.median(r):.3f} s")
    print(f"  ratio: {min(t) / min(r):.2f}x (min/min), "
          f"{statistics.median(t) / statistics.median(r):.2f}x (median/median)")


def stewart(n: int, repeat: int) -> None:
    from kinecal.io.csvtable import write_table
    from kinecal.io.geometry import load_geometry

    geom = load_geometry("liu2008-cmm")
    legs = geom.inverse(geom.random_poses(n, rng=0))
    with tempfile.TemporaryDirectory(prefix="kinecal-bench-") as tmp:
        path = Path(tmp) / "legs.csv"
        write_table(path, {f"l{i + 1}": legs[:, i] for i in range(6)})
        L = geom.check_legs(np.column_stack([legs[:, i] for i in range(6)]))
        geom.forward(L[:100])
        cmd = [*KINECAL, "stewart", "fk", "liu2008-cmm", str(path)]
        wall(cmd)
        t_cli, t_api = [], []
        for _ in range(repeat):
            t_cli.append(wall(cmd))
            t0 = time.perf_counter()
            geom.forward(L)
            t_api.append(time.perf_counter() - t0)
    print(f"kinecal stewart fk, {n} rows end to end: min {min(t_cli):.3f} s, median "
          f"{statistics.median(t_cli):.3f} s ({n / min(t_cli):.0f} rows/s at best)")
    print(f"  API StewartPlatform.forward on the same readings: min {min(t_api):.3f} s, "
          f"median {statistics.median(t_api):.3f} s ({n / min(t_api):.0f} rows/s)")
    print(f"  command-line throughput / API throughput: {min(t_api) / min(t_cli):.0%} "
          f"(min/min), {statistics.median(t_api) / statistics.median(t_cli):.0%} "
          "(median/median)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats, 10^4 Stewart rows")
    ap.add_argument("--repeat", type=int, default=None)
    args = ap.parse_args()
    repeat = args.repeat or (3 if args.quick else 9)
    py = [sys.executable, "-c"]
    compare("kinecal --help", [*KINECAL, "--help"], 'python -c "import numpy"',
            [*py, "import numpy"], repeat)
    compare("kinecal calibrate ur5 ur5-laser-tracker:grid --validate ur5-laser-tracker:random",
            [*KINECAL, "calibrate", "ur5", "ur5-laser-tracker:grid", "--validate",
             "ur5-laser-tracker:random"],
            'python -c "import numpy, scipy.linalg"', [*py, "import numpy, scipy.linalg"],
            repeat)
    stewart(10_000 if args.quick else 100_000, max(3, repeat // 2))


if __name__ == "__main__":
    main()
