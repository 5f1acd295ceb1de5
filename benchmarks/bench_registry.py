"""The registry over time: a simulated fleet's two years, 10 000 checks on Dask into
PostgreSQL, and ``kinecal check`` of one robot as a process.

Run ``python benchmarks/bench_registry.py [--quick] [--part fleet|dask|process]``.

fleet
    200 UR5 arms (true errors uniform within the model's tolerances on every parameter),
    each calibrated at the factory from 40 tracker poses (noise 0.02 mm per coordinate),
    then checked every month for two years at the 10 poses of ``plan-check`` (same noise,
    limit 0.2 mm), through the registry (SQLite) as ``kinecal check`` does it. 40 arms
    drift: one or two joint offsets at constant rates drawn so that each arm's error
    would reach the limit between months 3 and 20; one arm crashes between months 8 and
    9 (joint 3 offset +0.3 deg, link 2 bent by 0.1 deg); the others are steady. An arm
    found ``recalibrate`` is calibrated again (40 new poses of its arm as it is then), and
    drifts on. The truth decides: an arm *crosses* the limit at the first check where the
    RMS over the check poses of its current calibration's error exceeds 0.2 mm. Reported:
    for every crossing the delay to the first ``recalibrate`` (0: found at that very
    check), ``recalibrate`` before the crossing (early), and on the steady arms the
    share of checks, and of arms, with any other verdict than ``valid`` (false alarms).

dask
    10 000 checks (1000 robots registered in a fresh PostgreSQL database, 10 monthly
    checks each) by `kinecal.registry.fleet.check_fleet` on a local Dask cluster of 4
    single-threaded workers, while another process reads random robots' histories in a
    loop; one worker is killed (SIGKILL) a third of the way through (Dask restarts it and
    runs its chunks again). Then: records counted, keys and (robot, date) pairs unique,
    every check's calibration a calibration of its robot (``registry verify``).

process
    ``kinecal check`` of one robot (SQLite registry, 10 tracker poses) as a process,
    best of 7 runs, against ``python -c "import numpy, sqlalchemy"`` (the floor of any
    such tool in Python) and ``python -c "import numpy"``; CPU seconds (user + system)
    too, which a loaded machine leaves as they are.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from datetime import UTC, datetime, timedelta  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
NOISE = 0.02
LIMIT = 0.2
START = datetime(2026, 1, 1, tzinfo=UTC)


def _month(m: int) -> datetime:
    return START + timedelta(days=round(30.44 * m))


def _calibrate(model, truth, seed):
    """A calibration of the arm `truth` from 40 random tracker poses: its result JSON."""
    import kinecal
    from kinecal.calibration.serial.simulate import simulate

    sim = simulate(model, 40, errors=truth - model.nominal, noise=NOISE, rng=seed)
    return json.loads(json.dumps(kinecal.calibrate(model, sim.data).to_dict()))


def _true_error(model, q, p_hat, p_true) -> float:
    e = model.positions(q, p_hat) - model.positions(q, p_true)
    return float(np.sqrt((e ** 2).sum(axis=1).mean()))


def _fleet_arms(model, n, q, rng):
    """Truths, drift rates (API units per month) and the crash of the fleet."""
    from kinecal.calibration.serial.simulate import random_errors

    offsets = [f"theta{k}" for k in range(1, 6)]
    truths = [model.nominal + random_errors(model, rng) for _ in range(n)]
    rates = [np.zeros(model.n_params) for _ in range(n)]
    n_drift = max(2, n // 5)
    for i in range(n_drift):
        joints = rng.choice(offsets, size=int(rng.integers(1, 3)), replace=False)
        direction = np.zeros(model.n_params)
        direction[model.index(list(joints))] = rng.choice([-1, 1], len(joints)) * \
            rng.uniform(0.5, 1.0, len(joints))
        unit = _true_error(model, q, truths[i], truths[i] + 1e-4 * direction) / 1e-4
        months = rng.uniform(3, 20)
        rates[i] = direction * LIMIT / (unit * months)
    crash = n_drift  # the first steady arm crashes
    return truths, rates, n_drift, crash


def _crash(model, p):
    p = p.copy()
    p[model.index(["theta3"])[0]] += np.radians(0.3)
    p[model.index(["alpha2"])[0]] += np.radians(0.1)
    return p


def run_fleet(n: int, months: int, seed: int = 0, alpha: float | None = None) -> dict:
    """The fleet's two years (module docstring); the counts and delays."""
    import kinecal
    from kinecal.data import Measurements
    from kinecal.registry.fleet import check_robot
    from kinecal.registry.plan import plan_check
    from kinecal.registry.records import calibration_row, model_source
    from kinecal.registry.store import open_registry

    model = kinecal.load_model("ur5")
    q = plan_check(model, 10, seed=1).q
    rng = np.random.default_rng(seed)
    truths, rates, n_drift, crash = _fleet_arms(model, n, q, rng)
    tmp = Path(tempfile.mkdtemp(prefix="kinecal-fleet-"))
    db = str(tmp / "fleet.db")
    t0 = time.perf_counter()
    stats = {"checks": 0, "steady_checks": 0, "steady_alarms": 0, "steady_arms_alarmed": 0,
             "crossings": 0, "delays": [], "early": 0, "missed": 0, "censored": 0,
             "crash_first": None,
             "drifted_verdicts": 0, "recalibrations": 0, "n": n, "n_drift": n_drift}
    with open_registry(db) as reg:
        p_hat = []
        for i in range(n):
            doc = _calibrate(model, truths[i], [seed, i, 0])
            serial = f"UR5-{i:04d}"
            reg.add_event(serial, calibration_row(serial, doc, "factory.json",
                                                  source=model_source(None, doc),
                                                  date=START), current="arm")
            p_hat.append(_params(model, doc))
        t_cal = time.perf_counter() - t0
        for i in range(n):
            serial = f"UR5-{i:04d}"
            crossed_at, alarmed = None, False
            for m in range(1, months + 1):
                if i == crash and m == 9:  # between months 8 and 9, for good
                    truths[i] = _crash(model, truths[i])
                p_true = truths[i] + rates[i] * m
                err = _true_error(model, q, p_hat[i], p_true)
                if err > LIMIT and crossed_at is None:
                    crossed_at = m
                    stats["crossings"] += 1
                y = model.positions(q, p_true) + rng.normal(0, NOISE, (len(q), 3))
                _, stored, _ = check_robot(reg, serial, [Measurements(q, y)], limit=LIMIT,
                                           date=_month(m), **({} if alpha is None else
                                                              {"alpha": alpha}))
                verdict = stored["verdict"]
                stats["checks"] += 1
                if i == crash and m == 9:
                    stats["crash_first"] = verdict
                if i >= n_drift and not (i == crash and m >= 9):
                    stats["steady_checks"] += 1
                    if verdict != "valid":
                        stats["steady_alarms"] += 1
                        alarmed = True
                elif verdict == "drifted":
                    stats["drifted_verdicts"] += 1
                if verdict == "recalibrate":
                    if crossed_at is None:
                        stats["early"] += 1
                    else:
                        stats["delays"].append(m - crossed_at)
                    doc = _calibrate(model, p_true, [seed, i, m])
                    reg.add_event(serial, calibration_row(serial, doc, "recalibration.json",
                                                          source=model_source(None, doc),
                                                          date=_month(m) + timedelta(days=1)),
                                  current="arm")
                    p_hat[i] = _params(model, doc)
                    crossed_at = None  # the drift goes on from the new calibration
                    stats["recalibrations"] += 1
            if crossed_at is not None:  # crossed and not found by the end of the two years
                stats["missed"] += crossed_at < months - 1
                stats["censored"] += crossed_at >= months - 1
            stats["steady_arms_alarmed"] += alarmed
    stats["seconds_calibrations"] = t_cal
    stats["seconds"] = time.perf_counter() - t0
    stats["db_bytes"] = Path(db).stat().st_size
    return stats


def _params(model, doc):
    from kinecal.io.result_values import parameters_from_data

    return parameters_from_data(model, doc, Path("result.json"))


def _report_fleet(s: dict) -> None:
    steady = s["n"] - s["n_drift"] - 1
    delays = np.array(s["delays"], dtype=int)
    print(f"fleet: {s['n']} arms x 24 months: {s['checks']} checks, "
          f"{s['recalibrations']} recalibrations, {s['seconds']:.0f} s "
          f"({s['seconds_calibrations']:.0f} s of factory calibrations), registry "
          f"{s['db_bytes'] / 1e6:.1f} MB")
    print(f"  crossings of the limit: {s['crossings']}; found at the crossing's check: "
          f"{int((delays == 0).sum())}, one check later: {int((delays == 1).sum())}, "
          f"later: {int((delays > 1).sum())}; not found although two checks followed: "
          f"{s['missed']}; crossed at one of the last two checks, not yet found: "
          f"{s['censored']}; "
          f"recalibrate before the truth crossed: {s['early']}")
    print(f"  drifting arms' 'drifted' verdicts (warnings before the limit): "
          f"{s['drifted_verdicts']}")
    print(f"  steady arms: {steady}; false alarms {s['steady_alarms']} of "
          f"{s['steady_checks']} checks ({100 * s['steady_alarms'] / s['steady_checks']:.2f} "
          f"%), {s['steady_arms_alarmed']} of {steady} arms ever "
          f"({100 * s['steady_arms_alarmed'] / steady:.1f} %)")
    print(f"  crash: its first check after the crash says {s['crash_first']}")


def _pg():
    spec = importlib.util.spec_from_file_location("pgserver", ROOT / "tests" / "registry"
                                                  / "pgserver.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


READER = """
import sys, time, random
from kinecal.registry.store import open_registry
db, n, stop = sys.argv[1], int(sys.argv[2]), sys.argv[3]
import os
reads = checks_seen = bad = 0
with open_registry(db, write=False) as reg:
    while not os.path.exists(stop):
        h = reg.history(f"R-{random.randrange(n):05d}")
        cals = {e["id"] for e in h["events"] if e["kind"] == "calibration"}
        for e in h["events"]:
            if e["kind"] == "check":
                checks_seen += 1
                bad += e["calibration"] not in cals
        reads += 1
print(reads, checks_seen, bad)
"""


def run_dask(robots: int, per_robot: int, workers: int = 4) -> dict:
    """10 000 checks on Dask into PostgreSQL while another process reads (docstring)."""
    import signal
    import subprocess

    from distributed import Client, LocalCluster

    import kinecal
    from kinecal.data import Measurements
    from kinecal.registry.fleet import FleetCheck, check_fleet
    from kinecal.registry.plan import plan_check
    from kinecal.registry.records import calibration_row, model_source
    from kinecal.registry.store import open_registry
    from kinecal.registry.verify import verify_registry

    model = kinecal.load_model("ur5")
    q = plan_check(model, 10, seed=1).q
    out: dict = {}
    with _pg().postgres_server() as server:
        url = server.new_database()
        t0 = time.perf_counter()
        from kinecal.calibration.serial.simulate import random_errors

        rng = np.random.default_rng(5)
        p_true = model.nominal + random_errors(model, rng)
        doc = _calibrate(model, p_true, 1)  # every robot of this fleet is one arm
        with open_registry(url) as reg:
            for i in range(robots):
                serial = f"R-{i:05d}"
                reg.add_event(serial, calibration_row(serial, doc, "factory.json",
                                                      source=model_source(None, doc),
                                                      date=START), current="arm")
        out["seconds_register"] = time.perf_counter() - t0
        checks = []
        for m in range(1, per_robot + 1):
            for i in range(robots):
                y = model.positions(q, p_true) + rng.normal(0, NOISE, (len(q), 3))
                checks.append(FleetCheck(f"R-{i:05d}", (Measurements(q, y),),
                                         date=_month(m), limit=LIMIT))
        stop = Path(tempfile.mkdtemp()) / "stop"
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
        reader = subprocess.Popen([sys.executable, "-c", READER, url, str(robots), str(stop)],
                                  env=env, stdout=subprocess.PIPE, text=True)
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                          host="127.0.0.1", dashboard_address="127.0.0.1:0") as cluster, \
                Client(cluster) as client:
            ex = client.get_executor(pure=False)
            done = []
            killed = {}

            def on_result(o):
                done.append(o)
                if len(done) == len(checks) // 3 and not killed:
                    pids = client.run(os.getpid)
                    victim, pid = next(iter(pids.items()))
                    killed[victim] = pid
                    os.kill(pid, signal.SIGKILL)

            t0 = time.perf_counter()
            outcomes = check_fleet(url, checks, executor=ex, chunk=25, on_result=on_result)
            out["seconds_checks"] = time.perf_counter() - t0
        stop.touch()
        reads, seen, bad = map(int, reader.communicate(timeout=120)[0].split())
        out.update(reader_histories=reads, reader_checks_seen=seen, reader_inconsistent=bad,
                   killed_worker=bool(killed))
        with open_registry(url, write=False) as reg:
            problems, counts = verify_registry(reg)

            def tally(conn):
                rows = conn.exec_driver_sql(
                    "SELECT count(*), count(DISTINCT uid), count(DISTINCT (robot_id, date)) "
                    "FROM events WHERE kind = 'check'").fetchone()
                return tuple(int(v) for v in rows)

            n_checks, n_uid, n_pairs = reg.read(tally)
        out.update(checks_submitted=len(checks), outcomes=len(outcomes),
                   errors=sum(o.error is not None for o in outcomes),
                   new=sum(o.new for o in outcomes), stored=n_checks, unique_keys=n_uid,
                   unique_robot_dates=n_pairs, problems=problems, records=counts)
    return out


def _report_dask(d: dict) -> None:
    rate = d["checks_submitted"] / d["seconds_checks"]
    print(f"dask: {d['checks_submitted']} checks on 4 workers into PostgreSQL in "
          f"{d['seconds_checks']:.0f} s ({rate:.0f} checks/s; registering the robots "
          f"{d['seconds_register']:.0f} s); a worker killed: {d['killed_worker']}; checks "
          f"found stored already when their chunk ran again: {d['outcomes'] - d['new']}")
    print(f"  stored {d['stored']} checks, {d['unique_keys']} distinct keys, "
          f"{d['unique_robot_dates']} distinct (robot, date); outcomes {d['outcomes']}, "
          f"new {d['new']}, errors {d['errors']}; verify: "
          f"{'sound' if not d['problems'] else d['problems'][:3]}")
    print(f"  meanwhile another process read {d['reader_histories']} histories "
          f"({d['reader_checks_seen']} checks seen, {d['reader_inconsistent']} inconsistent)")


def _best(argv: list[str], rounds: int, cwd: Path) -> tuple[float, float]:
    """Best wall time and best CPU time (user + system of the child) of `argv`."""
    import resource
    import subprocess

    walls, cpus = [], []
    for _ in range(rounds):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(argv, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                       check=False)
        walls.append(time.perf_counter() - t0)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return min(walls), min(cpus)


def run_process(rounds: int = 7) -> dict:
    import subprocess

    tmp = Path(tempfile.mkdtemp(prefix="kinecal-check-"))
    kin = [sys.executable, "-m", "kinecal"]
    subprocess.run([*kin, "simulate", "ur5", "--poses", "40", "--noise", "0.02", "--seed",
                    "3", "--out", "cal.csv", "--truth-out", "truth.json"], cwd=tmp,
                   check=True, capture_output=True)
    subprocess.run([*kin, "calibrate", "ur5", "cal.csv", "--register", "SN-1", "--quiet"],
                   cwd=tmp, check=True, capture_output=True)
    subprocess.run([*kin, "plan-check", "ur5", "--out", "poses.csv"], cwd=tmp, check=True,
                   capture_output=True)
    subprocess.run([*kin, "simulate", "ur5", "--joints", "poses.csv", "--errors",
                    "truth.json", "--noise", "0.02", "--seed", "4", "--out", "few.csv"],
                   cwd=tmp, check=True, capture_output=True)
    out = {}
    for name, argv in (("check", [*kin, "check", "SN-1", "few.csv", "--limit", "0.2"]),
                       ("numpy+sqlalchemy", [sys.executable, "-c",
                                             "import numpy, sqlalchemy"]),
                       ("numpy", [sys.executable, "-c", "import numpy"])):
        out[name] = _best(argv, rounds, tmp)
    return out


def _report_process(p: dict) -> None:
    w, c = p["check"]
    print(f"process: kinecal check of one robot: best {w:.3f} s wall, {c:.3f} s CPU "
          f"(of {7} runs); python -c 'import numpy, sqlalchemy' {p['numpy+sqlalchemy'][0]:.3f} s "
          f"wall, {p['numpy+sqlalchemy'][1]:.3f} s CPU; 'import numpy' "
          f"{p['numpy'][0]:.3f} s wall; check / (numpy + sqlalchemy) = "
          f"{w / p['numpy+sqlalchemy'][0]:.2f}x wall, {c / p['numpy+sqlalchemy'][1]:.2f}x CPU")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--part", choices=["fleet", "dask", "process", "all"], default="all")
    ap.add_argument("--alpha", type=float, default=None, help="the checks' --alpha (default "
                    "kinecal check's)")
    args = ap.parse_args()
    if args.part in ("process", "all"):
        _report_process(run_process(3 if args.quick else 7))
    if args.part in ("fleet", "all"):
        _report_fleet(run_fleet(30 if args.quick else 200, 24, alpha=args.alpha))
    if args.part in ("dask", "all"):
        _report_dask(run_dask(100 if args.quick else 1000, 2 if args.quick else 10))


if __name__ == "__main__":
    main()
