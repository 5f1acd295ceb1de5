"""The registry's record, on SQLite and on a real PostgreSQL server alike: adding, listing,
showing, histories, the current calibration, retractions, append-only history, exports,
the check's verdicts and exit codes; and the same commands giving the same history on both
backends."""

from __future__ import annotations

import json

import numpy as np
import pytest


def _json(cli, *args):
    code, out, err = cli(*args)
    assert code == 0, err
    return json.loads(out)


def test_a_robot_s_record_round_trip(db, arm, cli, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    code, _, err = cli("registry", "add", "SN-1", arm.result, "--db", db, "--date",
                       "2026-01-05", "--operator", "ann", "--instrument", "tracker T1")
    assert code == 0, err
    assert "registered calibration 1 of ur5 for SN-1" in err
    code, _, err = cli("registry", "add", "SN-1", arm.result, "--db", db, "--force",
                       "--reason", "the same result again, on purpose", "--date",
                       "2026-02-01", "--no-current")
    assert code == 0, err
    robots = _json(cli, "registry", "list", "--db", db, "--json")["robots"]
    assert [(r["serial"], r["calibrations"], r["current"]["id"]) for r in robots] == [
        ("SN-1", 2, 1)]
    hist = _json(cli, "registry", "history", "SN-1", "--db", db, "--json")
    assert [(e["id"], e["kind"], e["current"]) for e in hist["events"]] == [
        (1, "calibration", True), (2, "calibration", False)]
    assert hist["events"][0]["operator"] == "ann"
    inputs = {e["name"]: e["sha256"] for e in hist["events"][0]["inputs"]}
    import hashlib

    assert inputs["RESULT"] == hashlib.sha256(arm.result.read_bytes()).hexdigest()
    code, _, err = cli("registry", "set-current", "SN-1", "2", "--db", db, "--reason",
                       "newer")
    assert code == 0, err
    assert _json(cli, "registry", "history", "SN-1", "--db", db, "--json")["current"] == {
        "arm": 2}
    # a retraction takes the record out of the history, its reason kept; current falls back
    code, _, err = cli("registry", "retract", "SN-1", "2", "--db", db, "--reason",
                       "wrong robot", "--force")
    assert code == 0, err
    hist = _json(cli, "registry", "history", "SN-1", "--db", db, "--json")
    assert [e["id"] for e in hist["events"]] == [1] and hist["current"] == {"arm": 1}
    assert hist["retracted"][0]["reason"] == "wrong robot"
    every = _json(cli, "registry", "history", "SN-1", "--db", db, "--json", "--retracted")
    assert [e["id"] for e in every["events"]] == [1, 2]
    assert every["events"][1]["retracted"]["reason"] == "wrong robot"
    assert [c["reason"] for c in hist["current_changes"]] == [None, "newer"]
    view = _json(cli, "registry", "show", "SN-1", "--db", db, "--json")
    assert view["current"]["arm"]["id"] == 1 and view["calibrations"] == 1


def test_history_is_append_only_in_the_database(db, arm, cli):
    """The triggers refuse UPDATE and DELETE whoever writes: no record is overwritten."""
    import sqlalchemy as sa

    from kinecal.registry.store import open_registry

    assert cli("registry", "add", "SN-2", arm.result, "--db", db)[0] == 0
    with open_registry(db) as reg:
        for sql in ("UPDATE events SET verdict = 'valid'", "DELETE FROM events",
                    "DELETE FROM robots", "UPDATE current_changes SET reason = 'x'"):
            with pytest.raises(sa.exc.DBAPIError, match="append-only"), \
                    reg.engine.connect() as conn, conn.begin():
                conn.exec_driver_sql(sql)
        assert reg.history("SN-2")["events"][0]["id"] == 1


def test_the_same_result_twice_is_refused_unless_forced_with_a_reason(db, arm, cli):
    assert cli("registry", "add", "SN-3", arm.result, "--db", db)[0] == 0
    code, _, err = cli("registry", "add", "SN-3", arm.result, "--db", db)
    assert code == 2 and "already in the registry as calibration 1" in err
    code, _, err = cli("registry", "add", "SN-3", arm.result, "--db", db, "--force")
    assert code == 2 and "--reason" in err
    code, _, err = cli("registry", "retract", "SN-3", "1", "--db", db, "--reason", "x")
    assert code == 2 and "--force" in err
    from kinecal.registry.store import open_registry

    with open_registry(db, write=False) as reg:
        assert len(reg.history("SN-3")["events"]) == 1


def test_unknown_robot_and_record_are_named(db, arm, cli):
    assert cli("registry", "add", "SN-4", arm.result, "--db", db)[0] == 0
    code, _, err = cli("registry", "history", "NOPE", "--db", db)
    assert code == 2 and "no robot 'NOPE'" in err and "SN-4" in err
    code, _, err = cli("registry", "set-current", "SN-4", "99", "--db", db)
    assert code == 2 and "has no calibration 99" in err


def test_export_writes_the_current_calibration(db, arm, cli, tmp_path):
    """registry export = kinecal export of the stored result, byte for byte."""
    assert cli("registry", "add", "SN-5", arm.result, "--db", db)[0] == 0
    for fmt, name in (("yaml", "m.yaml"), ("urdf", "m.urdf"), ("ur-kinematics", "k.yaml")):
        mine, theirs = tmp_path / f"reg-{name}", tmp_path / f"exp-{name}"
        code, _, err = cli("registry", "export", "SN-5", "--format", fmt, "--out", mine,
                           "--db", db)
        assert code == 0, err
        assert cli("export", arm.result, "--format", fmt, "--out", theirs)[0] == 0
        strip = (lambda t: "\n".join(x for x in t.splitlines() if "written by" not in x)) \
            if fmt != "yaml" else (lambda t: t)
        assert strip(mine.read_text()) == strip(theirs.read_text())
    import kinecal

    m = kinecal.load_model(tmp_path / "reg-m.yaml")
    res = kinecal.load_result(arm.result)
    q = np.radians([[10, -60, 40, 20, 30, 50]])
    np.testing.assert_allclose(m.positions(q), res.model.positions(q), atol=1e-9)


def test_check_verdicts_exit_codes_and_json(db, arm, cli):
    """valid 0, drifted 3, recalibrate 4, bad input 2; the JSON contract; stored."""
    assert cli("registry", "add", "SN-6", arm.result, "--db", db, "--date",
               "2026-01-01")[0] == 0
    cases = [("ok.csv", None, 0, "valid"),
             ("small.csv", arm.shifted("theta2", np.radians(0.03)), 3, "drifted"),
             ("big.csv", arm.shifted("theta2", np.radians(0.3)), 4, "recalibrate")]
    for k, (name, params, status, verdict) in enumerate(cases):
        path = arm.measure(name, params, seed=k)
        code, out, err = cli("check", "SN-6", path, "--limit", "1.0", "--json", "--db", db,
                             "--date", f"2026-0{k + 2}-01")
        assert code == status, err
        doc = json.loads(out)
        assert doc["verdict"] == verdict
        assert {"verdict", "statistic", "p_value", "limit", "poses"} <= set(doc)
        assert len(doc["poses"]) == 10 and doc["limit"] == 1.0 and doc["calibration"] == 1
        if verdict != "valid":
            change = doc["directions"]["theta2"]
            assert abs(change["change"] - (0.03 if verdict == "drifted" else 0.3)) < \
                4 * change["std"] + 1e-3
    few = arm.measure("few.csv", q=arm.q[:3])
    code, _, err = cli("check", "SN-6", few, "--db", db)
    assert code == 2 and "3 measured poses" in err
    hist = _json(cli, "registry", "history", "SN-6", "--db", db, "--json")
    assert [e.get("verdict") for e in hist["events"]] == [None, "valid", "drifted",
                                                         "recalibrate"]


def test_sqlite_and_postgresql_give_identical_histories(postgres, tmp_path, arm, cli,
                                                        monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    ok = arm.measure("same-ok.csv", seed=5)
    moved = arm.measure("same-moved.csv", arm.shifted("theta3", np.radians(0.1)), seed=6)
    out = {}
    for name, db in (("sqlite", str(tmp_path / "a.db")), ("pg", postgres.new_database())):
        monkeypatch.setenv("KINECAL_DB", db)  # the very same command lines
        steps = [
            ("registry", "add", "A-1", arm.result, "--date", "2026-01-01", "--operator", "o"),
            ("registry", "add", "A-2", arm.result, "--date", "2026-01-02"),
            ("check", "A-1", ok, "--date", "2026-02-01", "--limit", "0.5"),
            ("check", "A-1", moved, "--date", "2026-03-01", "--limit", "0.5"),
            ("registry", "add", "A-1", arm.result, "--date", "2026-03-02", "--force",
             "--reason", "recalibrated"),
            ("check", "A-1", ok, "--date", "2026-04-01", "--limit", "0.5"),
            ("registry", "retract", "A-2", "2", "--reason", "wrong arm", "--force"),
        ]
        for step in steps:
            code, _, err = cli(*step)
            assert code in (0, 3, 4), (step, err)
        out[name] = [_json(cli, "registry", "history", s, "--json", "--retracted")
                     for s in ("A-1", "A-2")]
        out[name].append(_json(cli, "registry", "list", "--json"))
    assert out["sqlite"] == out["pg"]
    verdicts = [e.get("verdict") for e in out["pg"][0]["events"]]
    assert verdicts == [None, "valid", "recalibrate", None, "valid"]


def test_a_hand_eye_calibration_has_its_own_current_and_exports_as_ros_tf(db, arm, cli,
                                                                           tmp_path):
    """A robot's camera mount (kinecal handeye --out) beside its arm calibration: current
    per subject; registry export --format ros-tf equals kinecal export's transform."""
    he = tmp_path / "he.json"
    assert cli("handeye", "handeye-tabb1", "--out", he)[0] == 0
    assert cli("registry", "add", "H-1", arm.result, "--db", db)[0] == 0
    code, _, err = cli("registry", "add", "H-1", he, "--db", db)
    assert code == 0 and "handeye calibration 2" in err
    hist = _json(cli, "registry", "history", "H-1", "--db", db, "--json")
    assert hist["current"] == {"arm": 1, "handeye": 2}
    mine, theirs = tmp_path / "mine.launch.py", tmp_path / "theirs.launch.py"
    code, out_mine, err = cli("registry", "export", "H-1", "--format", "ros-tf", "--out",
                              mine, "--db", db)
    assert code == 0, err
    code, out_theirs, _ = cli("export", he, "--format", "ros-tf", "--out", theirs)
    assert code == 0 and out_mine == out_theirs  # the same frames and transform
    body = [ln for ln in mine.read_text().splitlines() if not ln.startswith("# written")]
    assert body == [ln for ln in theirs.read_text().splitlines()
                    if not ln.startswith("# written")]
