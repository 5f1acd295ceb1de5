"""Reading a big measurement CSV: kinecal against numpy.loadtxt on the same file.

A UR5 measurement file of 2.5 million poses (``q1..q6`` in degrees with 4 decimals,
``x, y, z`` in mm with 4 decimals: about 200 MB) is written once; then, alternately and
each in a fresh process, ``kinecal.read_measurements(path, ur5)`` (header check, C-speed
parse, vectorised validation, joint units, the Measurements checks) and
``numpy.loadtxt(path, delimiter=",", skiprows=1)`` read it. Printed: wall time of the
read and the process's peak resident memory (``VmHWM``; both processes import numpy and
kinecal first, and the increase over that is printed too), minimum and maximum over the
runs.

A second file has one bad cell near its end: kinecal must name its row and column (the
checked pass), and the time of that is printed too.

Run: ``python benchmarks/bench_read.py [--quick] [--rows N] [--repeat R]``.
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


def write_file(path: Path, n: int, bad_row: int | None = None) -> None:
    """``n`` rows of q1..q6 (deg) and x, y, z (mm), 4 decimals, written a block at a time."""
    rng = np.random.default_rng(0)
    with open(path, "w") as fh:
        fh.write("q1,q2,q3,q4,q5,q6,x,y,z\n")
        for s in range(0, n, 200_000):
            m = min(200_000, n - s)
            block = np.round(np.column_stack([rng.uniform(-180, 180, (m, 6)),
                                              rng.uniform(-900, 900, (m, 3))]), 4)
            text = str(block.tolist())[2:-2].replace("], [", "\n").replace(", ", ",")
            if bad_row is not None and s <= bad_row - 1 < s + m:
                lines = text.split("\n")
                cells = lines[bad_row - 1 - s].split(",")
                cells[7] = "12.5.3"
                lines[bad_row - 1 - s] = ",".join(cells)
                text = "\n".join(lines)
            fh.write(text + "\n")


def _peak_bytes() -> int:
    """``VmHWM``: the peak resident set, reset by exec (getrusage's ru_maxrss is inherited
    from the parent process)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def child(kind: str, path: str) -> None:
    import kinecal
    from kinecal.errors import InputError

    if kind == "write":
        write_file(Path(path), int(os.environ["BENCH_ROWS"]),
                   int(os.environ["BENCH_BAD"]) if "BENCH_BAD" in os.environ else None)
        return
    model = kinecal.load_model("ur5")
    out = {"kind": kind, "base_bytes": _peak_bytes()}
    t0 = time.perf_counter()
    if kind == "kinecal":
        data = kinecal.read_measurements(path, model)
        out["rows"] = len(data)
    elif kind == "loadtxt":
        a = np.loadtxt(path, delimiter=",", skiprows=1)
        out["rows"] = a.shape[0]
    else:  # kinecal on the file with a bad cell
        try:
            kinecal.read_measurements(path, model)
            out["error"] = None
        except InputError as exc:
            out["error"] = exc.one_line()
    out["seconds"] = time.perf_counter() - t0
    out["peak_bytes"] = _peak_bytes()
    print(json.dumps(out))


def run(kind: str, path: Path, env: dict | None = None) -> dict | None:
    proc = subprocess.run([sys.executable, __file__, "--child", kind, str(path)],
                          capture_output=True, text=True, check=True,
                          env={**os.environ, **(env or {})})
    lines = proc.stdout.strip().splitlines()
    return json.loads(lines[-1]) if lines else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="250 000 rows, one run each")
    ap.add_argument("--rows", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    n = args.rows or (250_000 if args.quick else 2_500_000)
    repeat = args.repeat or (1 if args.quick else 3)
    with tempfile.TemporaryDirectory(prefix="kinecal-bench-") as tmp:
        path = Path(tmp) / "big.csv"
        t0 = time.perf_counter()
        run("write", path, {"BENCH_ROWS": str(n)})  # in a child: this process stays small
        size = path.stat().st_size
        print(f"{n} rows, {size / 1e6:.0f} MB (written in {time.perf_counter() - t0:.1f} s)")
        runs: dict[str, list] = {"kinecal": [], "loadtxt": []}
        for _ in range(repeat):
            for kind in runs:
                runs[kind].append(run(kind, path))
        for kind, label in (("kinecal", "kinecal.read_measurements"),
                            ("loadtxt", "numpy.loadtxt")):
            r = runs[kind]
            assert all(x["rows"] == n for x in r)
            s = [x["seconds"] for x in r]
            m = [x["peak_bytes"] / 1e6 for x in r]
            inc = [(x["peak_bytes"] - x["base_bytes"]) / 1e6 for x in r]
            print(f"  {label:<26} {min(s):6.2f}-{max(s):6.2f} s   peak RSS "
                  f"{min(m):5.0f}-{max(m):5.0f} MB ({min(inc):.0f}-{max(inc):.0f} MB above the "
                  "interpreter with numpy and kinecal loaded)")
        k = [x["seconds"] for x in runs["kinecal"]]
        lt = [x["seconds"] for x in runs["loadtxt"]]
        print(f"  time kinecal / loadtxt: {min(k) / min(lt):.2f}x (min/min), "
              f"{max(k) / max(lt):.2f}x (max/max)")
        path.unlink()
        bad = Path(tmp) / "bad.csv"
        run("write", bad, {"BENCH_ROWS": str(n), "BENCH_BAD": str(n - 10)})
        r = run("bad", bad)
        print(f"  a bad cell in row {n - 10}: {r['seconds']:.2f} s, peak RSS "
              f"{r['peak_bytes'] / 1e6:.0f} MB: {r['error']}")


if __name__ == "__main__":
    main()
