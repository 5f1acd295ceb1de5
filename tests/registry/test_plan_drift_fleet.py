"""plan-check's poses against random ones, drift rates and the projected crossing from a
simulated year of checks, fleets on Dask into PostgreSQL (no record lost or duplicated,
a chunk run twice), and the commands that write calibrations into the registry
(calibrate --register, batch --register)."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest


def test_plan_check_poses_reveal_the_usual_changes_better_than_random_ones():
    import kinecal
    from kinecal.calibration.serial.simulate import random_configurations
    from kinecal.registry.plan import _jacobian, plan_check

    m = kinecal.load_model("ur5")
    plan = plan_check(m, 8, seed=1, sigma=0.02, limit=0.2)
    names = list(plan.directions)
    cols = m.index(names)

    def logdet(q):
        J = _jacobian(m, q, cols).reshape(-1, len(cols))
        J = J / np.sqrt((J ** 2).mean(axis=0))
        return np.linalg.slogdet(J.T @ J + 1e-9 * np.eye(len(cols)))[1]

    ours = logdet(plan.q)
    rand = [logdet(random_configurations(m, 8, np.random.default_rng(s))) for s in range(30)]
    assert ours > max(rand)
    # theta2 (shoulder) at the limit is many noise sigmas out: the check will see it
    d = plan.directions["theta2"]
    assert d["kind"] == "offset" and d["at_limit"] / d["std"] > 10
    assert {"offset", "base", "bend"} == {v["kind"] for v in plan.directions.values()}


def _true_error(arm, cal_params, p):
    e = arm.model.positions(arm.q, cal_params) - arm.model.positions(arm.q, p)
    return float(np.sqrt((e ** 2).sum(axis=1).mean()))


def test_drift_rate_and_projected_crossing_from_a_year_of_checks(sqlite_db, arm, cli):
    """theta2 drifts 0.04 deg a year: monthly checks give its rate within three standard
    errors, and eight months of them project the crossing of the limit within two months
    of when the true error crosses it."""
    from kinecal.registry.drift import drift_summary
    from kinecal.registry.fleet import check_robot
    from kinecal.registry.store import open_registry

    rate = np.radians(0.04)  # per year
    limit = 0.5
    start = datetime(2026, 1, 1, tzinfo=UTC)
    assert cli("registry", "add", "DR-1", arm.result, "--db", sqlite_db, "--date",
               start.date().isoformat())[0] == 0
    cal_params = json.loads(arm.result.read_text())
    from kinecal.io.result_values import parameters_from_data

    p_hat = parameters_from_data(arm.model, cal_params, arm.result)
    years = np.arange(1, 9) / 12
    with open_registry(sqlite_db) as reg:
        for k, t in enumerate(years):
            p = arm.shifted("theta2", rate * t)
            path = arm.measure(f"month-{k}.csv", p, seed=100 + k)
            check_robot(reg, "DR-1", [path], limit=limit,
                        date=start + timedelta(days=365.25 * t))
        drift = drift_summary(reg.history("DR-1"))
    d = drift["directions"]["theta2"]
    assert abs(d["rate_per_year"] - 0.04) < 3 * d["rate_std"] and d["significant"]
    assert d["unit"] == "deg/year"
    # the true crossing: when the systematic error at the check poses reaches the limit
    ts = np.linspace(0, 5, 5001)
    err = [_true_error(arm, p_hat, arm.shifted("theta2", rate * t)) for t in ts]
    true_cross = start + timedelta(days=365.25 * ts[np.argmax(np.array(err) > limit)])
    proj = datetime.fromisoformat(drift["deviation"]["projected_crossing"])
    assert abs((proj - true_cross).days) < 61, (proj, true_cross)
    assert drift["deviation"]["growing"] and drift["calibration"] == 1


@pytest.fixture(scope="module")
def dask_client():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      host="127.0.0.1", dashboard_address="127.0.0.1:0") as cluster, \
            Client(cluster) as client:
        yield client


def test_fleet_checks_on_dask_into_postgresql_lose_and_duplicate_nothing(
        postgres, arm, dask_client):
    from kinecal.data import Measurements
    from kinecal.registry.fleet import FleetCheck, check_fleet
    from kinecal.registry.records import calibration_row, model_source
    from kinecal.registry.store import open_registry

    url = postgres.new_database()
    doc = json.loads(arm.result.read_text())
    serials = [f"F-{i:03d}" for i in range(30)]
    with open_registry(url) as reg:
        for s in serials:
            reg.add_event(s, calibration_row(s, doc, arm.result, source=model_source(
                None, doc)), current="arm")
    when = datetime(2026, 5, 1, tzinfo=UTC)
    checks = []
    for i, s in enumerate(serials):
        p = arm.shifted("theta2", np.radians(0.3)) if i % 10 == 0 else arm.truth
        y = arm.model.positions(arm.q, p) + np.random.default_rng(i).normal(0, 0.03,
                                                                          (len(arm.q), 3))
        checks.append(FleetCheck(s, (Measurements(arm.q, y),), date=when, limit=0.3))
    checks.append(FleetCheck("NOT-THERE", checks[0].data, date=when))
    ex = dask_client.get_executor(pure=False)
    first = check_fleet(url, checks, executor=ex, chunk=4)
    again = check_fleet(url, checks[:9], executor=ex, chunk=3)  # a rerun: found, not added
    assert [o.serial for o in first] == [c.serial for c in checks]
    assert first[-1].error and "NOT-THERE" in first[-1].error
    assert all(o.new and o.id for o in first[:-1])
    assert [o.id for o in again] == [o.id for o in first[:9]] and not any(o.new for o in again)
    verdicts = [o.verdict for o in first[:-1]]
    assert [v for i, v in enumerate(verdicts) if i % 10 == 0] == ["recalibrate"] * 3
    with open_registry(url, write=False) as reg:
        rows = reg.robots()
        assert sum(r["checks"] for r in rows) == 30
        assert all(r["checks"] == 1 for r in rows)


def test_calibrate_and_batch_register(tmp_path, cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli("simulate", "ur5", "--poses", "30", "--noise", "0.02", "--seed", "3",
               "--out", "a.csv")[0] == 0
    code, _, err = cli("calibrate", "ur5", "a.csv", "--register", "CB-1", "--quiet")
    assert code == 0, err
    code, _, err = cli("calibrate", "ur5", "a.csv", "--db", "x.db", "--quiet")
    assert code == 2 and "--register" in err
    (tmp_path / "jobs.yaml").write_text(
        "jobs:\n  - {name: arm-1, model: ur5, data: a.csv, serial: CB-2}\n"
        "  - {name: arm-2, model: ur5, data: a.csv}\n"
        "study: {model: ur5, methods: [lm], seeds: 1, noise: [0.01], poses: [30]}\n")
    for rerun in (False, True):
        code, _, err = cli("batch", "jobs.yaml", "--out", "res", "--register", "--workers",
                           "1", "--quiet")
        assert code == 0, err
        assert ("0 calibrations recorded, 2 recorded already" if rerun else
                "2 calibrations recorded, 0 recorded already") in err
    code, out, _ = cli("registry", "list", "--json")
    robots = {r["serial"]: r for r in json.loads(out)["robots"]}
    assert set(robots) == {"CB-1", "CB-2", "arm-2"}  # the study's jobs have no robot
    assert all(r["calibrations"] == 1 for r in robots.values())
    code, out, _ = cli("registry", "history", "CB-1", "--json")
    ev = json.loads(out)["events"][0]
    import hashlib

    inputs = {e["name"]: e["sha256"] for e in ev["inputs"]}
    assert set(inputs) == {"MODEL", "DATA 1"}
    assert inputs["DATA 1"] == hashlib.sha256((tmp_path / "a.csv").read_bytes()).hexdigest()
    assert ev["command"].startswith("kinecal calibrate ur5 a.csv --register CB-1")
