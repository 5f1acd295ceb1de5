"""Command-line start-up and end-to-end throughput, timed as subprocesses.

Each command runs `--repeat` times, interleaved with its reference, and the minimum and
median wall times are printed (the machine is shared: the minimum is the least disturbed
run, the median the typical one):

* ``kinecal --help`` against ``python -c "import numpy"``;
* ``kinecal fk ur5 ONE.csv`` (one pose: a script asking per target) against the same
  product written with numpy in a ``python -c`` script;
* ``kinecal calibrate ur5 ur5-laser-tracker:grid --validate ur5-laser-tracker:random``
  against ``python -c "import numpy, scipy.linalg"``;
* ``kinecal stewart fk liu2008-cmm LEGS.csv`` on 10^5 leg readings (the CSV written
  first, from random workspace poses) against the API's throughput: the same solve,
  ``StewartPlatform.forward`` on the in-memory readings, timed in this process;
* ``kinecal calibrate ur5 DATA.csv`` on 10^4 and 10^5 simulated poses: peak resident
  memory of the process, per pose beyond the smaller run;
* ``kinecal compensate`` of a 10^6-row joint program: time and peak memory.

``kinecal`` is run as ``python -m kinecal`` with this interpreter (what the console script
does: import ``kinecal.cli`` and call ``main``). Every process runs with compiled bytecode,
as an installed package does: ``PYTHONDONTWRITEBYTECODE`` is dropped and the ``.pyc`` files
go to a temporary ``PYTHONPYCACHEPREFIX`` (written by the warm-up run, for the peers'
modules too; the source tree is not touched). Without them, a checkout whose environment
sets ``PYTHONDONTWRITEBYTECODE`` compiles kinecal's 40-odd modules on every command (about
0.05-0.15 s, more than the work of ``kinecal fk``), while numpy's came compiled from pip.
Times are the wall time and the CPU time (user + system, ``RUSAGE_CHILDREN``) of each
process; the CPU time moves less with the other jobs' load.

Run: ``python benchmarks/bench_cli.py [--quick] [--repeat R] [--parts help,fk,calibrate,
stewart,memory,compensate]``. ``PYTHONPATH=OTHER/src`` runs another checkout's kinecal
(a before-and-after pair in one session).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# compiled bytecode for every child process, as an installed package has (module docstring)
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
os.environ.setdefault("PYTHONPYCACHEPREFIX", tempfile.mkdtemp(prefix="kinecal-bench-pyc-"))

import numpy as np

KINECAL = [sys.executable, "-m", "kinecal"]


def timed(cmd: list[str], stdout=subprocess.DEVNULL) -> tuple[float, float]:
    """Wall and CPU (user + system) seconds of one run of `cmd`."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, stdout=stdout, stderr=subprocess.DEVNULL, check=True)
    t = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return t, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def wall(cmd: list[str], stdout=subprocess.DEVNULL) -> float:
    return timed(cmd, stdout)[0]


def compare(label: str, cmd: list[str], ref_label: str, ref: list[str], repeat: int) -> None:
    timed(cmd), timed(ref)  # warm the file cache and write the bytecode
    t, r = [], []
    for _ in range(repeat):
        t.append(timed(cmd))
        r.append(timed(ref))
    tw, rw = [w for w, _ in t], [w for w, _ in r]
    tc, rc = min(c for _, c in t), min(c for _, c in r)
    print(f"{label}: min {min(tw):.3f} s, median {statistics.median(tw):.3f} s, CPU {tc:.3f} s")
    print(f"  {ref_label}: min {min(rw):.3f} s, median {statistics.median(rw):.3f} s, "
          f"CPU {rc:.3f} s")
    print(f"  ratio: {min(tw) / min(rw):.2f}x (min/min), "
          f"{statistics.median(tw) / statistics.median(rw):.2f}x (median/median), "
          f"CPU {tc / rc:.2f}x (load {os.getloadavg()[0]:.1f})")


#: the bundled ur5 model (D-H table, tool point; mm) at one pose: the peer of ``kinecal fk``
FK_SCRIPT = """import numpy as np
d = [89.159, 0, 0, 109.15, 94.65, 82.3]
a = [0, -425, -392.25, 0, 0, 0]
al = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]
q = np.radians([0, 10, 20, 30, 40, 50])
T = np.eye(4)
for i in range(6):
    ct, st, ca, sa = np.cos(q[i]), np.sin(q[i]), np.cos(al[i]), np.sin(al[i])
    T = T @ np.array([[ct, -st * ca, st * sa, a[i] * ct], [st, ct * ca, -ct * sa, a[i] * st],
                      [0, sa, ca, d[i]], [0, 0, 0, 1]])
p = T @ np.array([0.0, 0.07, 31.0, 1.0])  # the bundled model's tool point
print("x,y,z")
print(",".join(repr(float(v)) for v in p[:3]))
"""


def one_pose_fk(repeat: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        q = Path(tmp) / "one.csv"
        q.write_text("q1,q2,q3,q4,q5,q6\n0,10,20,30,40,50\n")
        compare("kinecal fk ur5 ONE.csv (one pose)", [*KINECAL, "fk", "ur5", str(q)],
                "python -c (numpy D-H product of the same pose)",
                [sys.executable, "-c", FK_SCRIPT], repeat)


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
        t_cli, t_api, c_cli, c_api = [], [], [], []
        for _ in range(repeat):
            w, c = timed(cmd)
            t_cli.append(w)
            c_cli.append(c)
            t0, c0 = time.perf_counter(), time.process_time()
            geom.forward(L)
            t_api.append(time.perf_counter() - t0)
            c_api.append(time.process_time() - c0)
    print(f"kinecal stewart fk, {n} rows end to end: min {min(t_cli):.3f} s, median "
          f"{statistics.median(t_cli):.3f} s ({n / min(t_cli):.0f} rows/s at best), "
          f"CPU {min(c_cli):.3f} s")
    print(f"  API StewartPlatform.forward on the same readings: min {min(t_api):.3f} s, "
          f"median {statistics.median(t_api):.3f} s ({n / min(t_api):.0f} rows/s), "
          f"CPU {min(c_api):.3f} s")
    print(f"  command-line throughput / API throughput: {min(t_api) / min(t_cli):.0%} "
          f"(min/min), {statistics.median(t_api) / statistics.median(t_cli):.0%} "
          f"(median/median), CPU {min(c_api) / min(c_cli):.0%} (load {os.getloadavg()[0]:.1f})")


# VmHWM: the process's own peak resident set (getrusage's ru_maxrss keeps the parent's
# peak across fork and exec)
_PEAK = ("import sys\nfrom kinecal.cli import main\nrc = main(sys.argv[1:])\n"
         "hwm = [ln.split()[1] for ln in open('/proc/self/status') if ln.startswith('VmHWM')]\n"
         "sys.stderr.write(f'MAXRSS {hwm[0]}\\n')\nsys.exit(rc)")


def peak_kb(args: list[str]) -> int:
    """Peak resident memory (kB, ``VmHWM``) of one ``kinecal ARGS`` process (Linux)."""
    out = subprocess.run([sys.executable, "-c", _PEAK, *args], capture_output=True, text=True,
                         check=True)
    return int(out.stderr.rsplit("MAXRSS ", 1)[1].split()[0])


def calibrate_memory(sizes: tuple[int, ...], repeat: int) -> None:
    """``kinecal calibrate ur5 DATA.csv`` on simulated poses: peak memory per pose beyond
    the smallest size (the command without --out or --json builds no result dictionary)."""
    from kinecal.calibration.serial.simulate import simulate
    from kinecal.io.measurements import write_measurements
    from kinecal.io.models import load_model

    model = load_model("ur5")
    with tempfile.TemporaryDirectory(prefix="kinecal-bench-") as tmp:
        peaks = {}
        for n in sizes:
            path = Path(tmp) / f"meas{n}.csv"
            sim = simulate(model, n, errors="random", noise=0.01, rng=1)
            write_measurements(path, sim.data, model)
            peaks[n] = min(peak_kb(["calibrate", "ur5", str(path), "--quiet"])
                           for _ in range(repeat))
    n0 = sizes[0]
    for n in sizes[1:]:
        per = (peaks[n] - peaks[n0]) * 1024 / (n - n0)
        print(f"kinecal calibrate ur5, {n} poses: peak {peaks[n] / 1024:.0f} MB ({n0} poses: "
              f"{peaks[n0] / 1024:.0f} MB): {per:.0f} B per pose beyond {n0}")


def compensate_big(n: int) -> None:
    """``kinecal compensate`` of an n-row UR5 joint program (random configurations within
    70 % of the joint ranges) with a calibrated model: wall time and peak memory of the
    process (the program is streamed a block of rows at a time)."""
    from kinecal.calibration.serial.simulate import random_configurations
    from kinecal.cli import main as cli
    from kinecal.io.models import load_model

    model = load_model("ur5")
    with tempfile.TemporaryDirectory(prefix="kinecal-bench-") as tmp:
        d = Path(tmp)
        cli(["simulate", "ur5", "--poses", "60", "--noise", "0.01", "--seed", "1", "--out",
             str(d / "meas.csv"), "--quiet"])
        cli(["calibrate", "ur5", str(d / "meas.csv"), "--model-out", str(d / "cal.yaml"),
             "--quiet"])
        rng = np.random.default_rng(3)
        prog = d / "program.csv"
        with open(prog, "w") as fh:
            fh.write("q1,q2,q3,q4,q5,q6\n")
            for s in range(0, n, 100_000):
                q = np.degrees(random_configurations(model, min(100_000, n - s), rng) * 0.7)
                fh.write("\n".join(",".join(repr(v) for v in row) for row in q.tolist()) + "\n")
        t0 = time.perf_counter()
        kb = peak_kb(["compensate", str(d / "cal.yaml"), str(prog), "--out",
                      str(d / "out.csv"), "--quiet"])
        t = time.perf_counter() - t0
    print(f"kinecal compensate, {n} joint-program rows: {t:.0f} s ({n / t:.0f} rows/s), peak "
          f"{kb / 1024:.0f} MB ({kb * 1024 / n:.0f} B per row)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats, 10^4 Stewart rows")
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument("--compensate-rows", type=int, default=None,
                    help="rows of the compensated program (default 10^6, quick 2 x 10^4)")
    ap.add_argument("--parts", default="help,fk,calibrate,stewart,memory,compensate",
                    help="comma-separated parts to run")
    args = ap.parse_args()
    parts = set(args.parts.split(","))
    repeat = args.repeat or (3 if args.quick else 9)
    py = [sys.executable, "-c"]
    import kinecal

    print(f"kinecal from {Path(kinecal.__file__).parent}")
    if "help" in parts:
        compare("kinecal --help", [*KINECAL, "--help"], 'python -c "import numpy"',
                [*py, "import numpy"], repeat)
    if "fk" in parts:
        one_pose_fk(repeat)
    if "calibrate" in parts:
        compare("kinecal calibrate ur5 ur5-laser-tracker:grid --validate "
                "ur5-laser-tracker:random",
                [*KINECAL, "calibrate", "ur5", "ur5-laser-tracker:grid", "--validate",
                 "ur5-laser-tracker:random"],
                'python -c "import numpy, scipy.linalg"', [*py, "import numpy, scipy.linalg"],
                repeat)
    if "stewart" in parts:
        stewart(10_000 if args.quick else 100_000, max(3, repeat // 2))
    if "memory" in parts:
        calibrate_memory((10_000, 100_000) if not args.quick else (2_000, 20_000), 2)
    if "compensate" in parts:
        compensate_big(args.compensate_rows or (20_000 if args.quick else 1_000_000))


if __name__ == "__main__":
    main()
