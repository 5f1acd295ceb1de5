"""Nothing lost: the store stays consistent and the command says what happened, under a
registry written by a newer kinecal, a damaged or foreign file, a read-only registry, a
full disk, SIGKILL in the middle of an add, and 8 processes adding and checking at once.
Real processes, a real PostgreSQL server; no mock."""

from __future__ import annotations

import hashlib
import os
import resource
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

ENV = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}


def kinecal(*args, cwd=None, preexec=None, timeout=300) -> subprocess.CompletedProcess:
    """``kinecal ARGS`` as a process of its own."""
    return subprocess.run([sys.executable, "-m", "kinecal", *map(str, args)], cwd=cwd,
                          env=ENV, capture_output=True, text=True, timeout=timeout,
                          preexec_fn=preexec)


def digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _sound(db: str) -> dict:
    from kinecal.registry.store import open_registry
    from kinecal.registry.verify import verify_registry

    with open_registry(db, write=False) as reg:
        problems, counts = verify_registry(reg)
    assert problems == []
    return counts


def test_a_newer_kinecal_s_registry_is_refused_with_its_version(db, arm, cli):
    from kinecal.registry.store import open_registry

    assert cli("registry", "add", "N-1", arm.result, "--db", db)[0] == 0
    with open_registry(db) as reg, reg.engine.connect() as conn, conn.begin():
        conn.exec_driver_sql("UPDATE alembic_version SET version_num = 'r0042'")
        conn.exec_driver_sql("UPDATE registry_info SET value = '7' WHERE key = 'schema'")
        conn.exec_driver_sql("UPDATE registry_info SET value = '3.1.0' WHERE key = 'kinecal'")
    before = digest(db) if not db.startswith("postgresql") else None
    for args in (("registry", "list"), ("registry", "add", "N-1", arm.result, "--force",
                                        "--reason", "x")):
        code, _, err = cli(*args, "--db", db)
        assert code == 2
        assert "written by kinecal 3.1.0 (registry schema 7, revision r0042)" in err
        assert "upgrade kinecal" in err
    if before is not None:
        assert digest(db) == before


def test_a_damaged_sqlite_file_is_detected_and_never_rewritten(sqlite_db, arm, cli):
    assert cli("registry", "add", "D-1", arm.result, "--db", sqlite_db)[0] == 0
    assert cli("registry", "add", "D-2", arm.result, "--db", sqlite_db)[0] == 0
    data = bytearray(Path(sqlite_db).read_bytes())
    page = 4096
    assert len(data) > 4 * page
    data[2 * page: 2 * page + 200] = b"\xa5" * 200  # a b-tree page's header destroyed
    Path(sqlite_db).write_bytes(bytes(data))
    before = digest(sqlite_db)
    code, _, err = cli("registry", "add", "D-3", arm.result, "--db", sqlite_db)
    assert code == 2 and "damaged" in err and ".recover" in err
    code, _, err = cli("registry", "verify", "--db", sqlite_db)
    assert code != 0
    assert digest(sqlite_db) == before
    # not SQLite at all, or a database of someone else's: refused, left as it is
    other = Path(sqlite_db).with_name("notes.db")
    other.write_text("my notes\n")
    code, _, err = cli("registry", "add", "D-3", arm.result, "--db", other)
    assert code == 2 and "not an SQLite database" in err
    assert other.read_text() == "my notes\n"
    import sqlite3

    foreign = Path(sqlite_db).with_name("foreign.db")
    with sqlite3.connect(foreign) as conn:
        conn.execute("CREATE TABLE parts (id INTEGER)")
    before = digest(foreign)
    code, _, err = cli("registry", "add", "D-3", arm.result, "--db", foreign)
    assert code == 2 and "no kinecal registry in it" in err
    assert digest(foreign) == before


def _read_only(folder: Path, args: list) -> subprocess.CompletedProcess:
    """Run kinecal with `folder` read-only: its files' write bits off (non-root), or (root,
    whom file modes do not stop) the folder mounted read-only in a mount namespace of the
    process's own."""
    if os.geteuid() != 0:
        for p in [folder, *folder.iterdir()]:
            p.chmod(0o555 if p.is_dir() else 0o444)
        try:
            return kinecal(*args)
        finally:
            for p in [folder, *folder.iterdir()]:
                p.chmod(0o755 if p.is_dir() else 0o644)
    script = 'mount --bind -o ro "$0" "$0" && exec "$@"'
    return subprocess.run(["unshare", "-m", "--propagation", "private", "sh", "-c", script,
                           str(folder), sys.executable, "-m", "kinecal", *map(str, args)],
                          env=ENV, capture_output=True, text=True, timeout=300)


def test_a_read_only_registry_is_read_and_never_written(tmp_path, arm, cli, postgres):
    folder = tmp_path / "ro"
    folder.mkdir()
    db = folder / "kinecal.db"
    assert cli("registry", "add", "R-1", arm.result, "--db", db)[0] == 0
    before = digest(db)
    done = _read_only(folder, ["registry", "add", "R-2", arm.result, "--db", db])
    assert done.returncode == 2, done.stderr
    assert "read-only" in done.stderr and "nothing was recorded" in done.stderr
    done = _read_only(folder, ["registry", "history", "R-1", "--db", db, "--json"])
    assert done.returncode == 0, done.stderr
    assert '"serial": "R-1"' in done.stdout
    assert digest(db) == before
    # PostgreSQL: a database whose transactions are read-only
    url = postgres.new_database()
    assert cli("registry", "add", "R-1", arm.result, "--db", url)[0] == 0
    import psycopg

    name = url.split("@/", 1)[1].split("?")[0]
    with psycopg.connect(host=str(postgres.socket_dir), port=postgres.port, user="kinecal",
                         dbname="postgres", autocommit=True) as conn:
        conn.execute(f'ALTER DATABASE "{name}" SET default_transaction_read_only = on')
    code, _, err = cli("registry", "add", "R-2", arm.result, "--db", url)
    assert code == 2 and "read-only" in err and "nothing was recorded" in err
    code, out, _ = cli("registry", "list", "--db", url, "--json")
    assert code == 0 and '"R-2"' not in out and '"R-1"' in out


def test_a_full_disk_leaves_the_registry_as_it_was(tmp_path, arm, cli):
    """The file size limit (ulimit -f) stops SQLite's writes as a full disk would."""
    db = tmp_path / "kinecal.db"
    assert cli("registry", "add", "F-1", arm.result, "--db", db)[0] == 0
    report = tmp_path / "big.html"
    report.write_bytes(os.urandom(3_000_000))  # beyond what the limit lets the file grow
    size = db.stat().st_size

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (size + 200_000, size + 200_000))

    done = kinecal("registry", "add", "F-2", arm.result, "--report", report, "--db", db,
                   preexec=limit)
    assert done.returncode == 1, done.stderr
    assert "nothing was recorded" in done.stderr and "Traceback" not in done.stderr
    counts = _sound(str(db))
    assert counts == {"robots": 1, "records": 1}
    assert cli("registry", "add", "F-2", arm.result, "--db", db)[0] == 0  # and it goes on


def _in_transaction(backend: str, db: str) -> bool:
    """Whether an add is inside its write transaction now: SQLite's rollback journal
    exists, or PostgreSQL shows another session with an open transaction."""
    if backend == "sqlite":
        return Path(db + "-journal").exists()
    import psycopg

    from kinecal.registry.location import locate

    url = locate(db).target.replace("postgresql+psycopg://", "postgresql://")
    with psycopg.connect(url, autocommit=True) as conn:
        n = conn.execute("SELECT count(*) FROM pg_stat_activity WHERE datname = "
                         "current_database() AND pid <> pg_backend_pid() AND xact_start "
                         "IS NOT NULL AND query ILIKE '%INSERT%'").fetchone()[0]
    return n > 0


@pytest.mark.parametrize("backend", ["sqlite", "postgresql"])
def test_sigkill_in_the_middle_of_an_add(backend, tmp_path, arm, request):
    """Adds killed inside their write transaction (seen from outside: the journal, the
    server's open transaction), a little later each time: every record is there whole or
    not at all, the store is sound, and the next add works (SQLite rolls the hot journal
    back)."""
    db = str(tmp_path / "kinecal.db") if backend == "sqlite" else \
        request.getfixturevalue("postgres").new_database()
    report = tmp_path / "report.html"
    report.write_bytes(os.urandom(24_000_000))
    done = kinecal("registry", "add", "K-0", arm.result, "--report", report, "--db", db)
    assert done.returncode == 0, done.stderr
    inside = 0
    for k in range(6):
        proc = subprocess.Popen([sys.executable, "-m", "kinecal", "registry", "add",
                                 f"K-{k + 1}", str(arm.result), "--report", str(report),
                                 "--db", db], env=ENV, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline:
            if _in_transaction(backend, db):
                inside += 1
                break
            time.sleep(0.002)
        time.sleep(0.01 * k)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        _sound(db)  # opening rolls a hot journal back
    from kinecal.registry.store import open_registry

    with open_registry(db, write=False) as reg:
        for r in reg.robots():
            ev = reg.current(r["serial"])
            assert ev["report"] == report.read_bytes()  # all of it, never a part
        assert len(reg.robots()) < 7  # some adds did not happen
    assert inside >= 4, "the kills did not land inside transactions: the test proves nothing"
    done = kinecal("registry", "add", "K-after", arm.result, "--db", db)
    assert done.returncode == 0, done.stderr


WORKER = textwrap.dedent("""
    import sys, numpy as np
    from kinecal.registry.store import open_registry
    from kinecal.registry.fleet import check_robot
    from kinecal.registry.records import calibration_row, model_source
    from kinecal._files import read_json
    db, me, result, data = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
    doc = read_json(result)
    with open_registry(db) as reg:
        for k in range(4):
            serial = f"P{(me + k) % 8}"  # robots shared between the processes
            row = calibration_row(serial, doc, result, source=model_source(None, doc),
                                  force_reason=f"process {me} add {k}")
            reg.add_event(serial, row, current="arm", reason=f"process {me} add {k}")
            _, stored, new = check_robot(reg, serial, [data])
            assert new and stored["verdict"] in ("valid", "drifted", "recalibrate")
    print("done", me)
""")


def test_eight_processes_adding_and_checking_at_once(db, arm, tmp_path):
    script = tmp_path / "worker.py"
    script.write_text(WORKER)
    data = [arm.measure(f"eight-{me}.csv", seed=80 + me) for me in range(8)]
    procs = [subprocess.Popen([sys.executable, str(script), db, str(me), str(arm.result),
                               str(data[me])], env=ENV, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for me in range(8)]
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (_out, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err
    counts = _sound(db)
    assert counts == {"robots": 8, "records": 64}
    from kinecal.registry.store import open_registry

    with open_registry(db, write=False) as reg:
        for r in reg.robots():
            hist = reg.history(r["serial"])
            kinds = [e["kind"] for e in hist["events"]]
            assert kinds.count("calibration") == 4 and kinds.count("check") == 4
            cal_ids = {e["id"] for e in hist["events"] if e["kind"] == "calibration"}
            assert {e["calibration"] for e in hist["events"] if e["kind"] == "check"} \
                <= cal_ids
            assert len(hist["current_changes"]) == 4


def test_unwritable_folder_and_missing_registry_are_named(tmp_path, arm, cli):
    code, _, err = cli("registry", "list", "--db", tmp_path / "none.db")
    assert code == 2 and "no registry at" in err
    assert not (tmp_path / "none.db").exists()
    code, _, err = cli("registry", "add", "X", arm.result, "--db", tmp_path / "no" / "k.db")
    assert code == 2 and "does not exist" in err
    code, _, err = cli("registry", "list", "--db", "mysql://h/db")
    assert code == 2 and "postgresql://" in err
    shutil.rmtree(tmp_path / "no", ignore_errors=True)


def test_without_the_registry_extra_the_command_says_what_to_install(tmp_path):
    code = ("import sys; sys.modules['sqlalchemy'] = None\n"
            "from kinecal.cli import main\n"
            "sys.exit(main(['registry', 'list', '--db', sys.argv[1]]))")
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path / "k.db")], env=ENV,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "pip install 'kinecal[registry]'" in done.stderr and "Traceback" not in done.stderr


def test_an_output_on_the_registry_file_is_refused(sqlite_db, arm, cli):
    assert cli("registry", "add", "O-1", arm.result, "--db", sqlite_db)[0] == 0
    before = digest(sqlite_db)
    for args in (("registry", "report", "--fleet", sqlite_db),
                 ("registry", "history", "O-1", "--report", sqlite_db),
                 ("registry", "export", "O-1", "--format", "yaml", "--out", sqlite_db),
                 ("check", "O-1", arm.measure("o.csv"), "--out", sqlite_db)):
        code, _, err = cli(*args, "--db", sqlite_db)
        assert code == 2 and "is also the input --db" in err, (args, err)
    assert digest(sqlite_db) == before


def test_a_check_starved_by_other_writers_is_stored_under_the_write_lock(db, arm, tmp_path):
    """When the current calibration keeps changing between reading it and writing the
    check (other processes adding calibrations), the check is not given up: its last
    attempt holds the registry's write lock from reading to writing (SQLite's file lock,
    PostgreSQL's row lock). ``attempts=0`` takes that path at once; a writer that changes
    the current calibration during every optimistic attempt forces it too."""
    from kinecal._files import read_json
    from kinecal.registry.fleet import check_robot
    from kinecal.registry.records import calibration_row, model_source
    from kinecal.registry.store import open_registry

    doc = read_json(arm.result)
    data = arm.measure("starved.csv", seed=91)
    later = arm.measure("starved-later.csv", seed=92)

    def last_check(reg):
        return [e for e in reg.history("S1")["events"] if e["kind"] == "check"][-1]

    def add(reg, k):
        row = calibration_row("S1", doc, arm.result, source=model_source(None, doc),
                              force_reason=f"add {k}")
        return reg.add_event("S1", row, current="arm", reason=f"add {k}")

    with open_registry(db) as reg:
        add(reg, 0)
        _, stored, new = check_robot(reg, "S1", [data], attempts=0)
        assert new and stored["verdict"] in ("valid", "drifted", "recalibrate")
        assert last_check(reg)["calibration"] == reg.current("S1")["id"]
        if db.startswith("postgresql"):
            return  # one transaction with the robot's row locked, always
        # SQLite: every optimistic attempt sees another calibration made current meanwhile
        made = []
        real_make_current = reg.current

        def changing_current(serial, subject="arm"):
            ev = real_make_current(serial, subject)
            made.append(add(reg, len(made) + 1))
            return ev

        reg.current = changing_current
        try:
            _, stored, new = check_robot(reg, "S1", [later], attempts=3)
        finally:
            reg.current = real_make_current
        assert new and len(made) == 3
        assert last_check(reg)["calibration"] == reg.current("S1")["id"]  # on the newest
