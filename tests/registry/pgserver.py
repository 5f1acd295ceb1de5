"""A throw-away PostgreSQL server for the registry's tests and benchmarks: Debian's binaries
(``/usr/lib/postgresql/*/bin``: initdb, pg_ctl) run in a temporary folder, listening on a
unix socket only, never a system cluster. As root the server runs as ``nobody`` (PostgreSQL
refuses root), through ``runuser``. Installed by ``make test`` when missing
(``.ci/install-postgres``).
"""

from __future__ import annotations

import contextlib
import glob
import os
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

__all__ = ["PostgresServer", "bin_dir", "postgres_server"]


def bin_dir() -> Path | None:
    """The newest PostgreSQL server's bin folder (None when not installed)."""
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"),
                   key=lambda p: int(Path(p).parts[-3]) if Path(p).parts[-3].isdigit() else 0)
    if found:
        return Path(found[-1]).parent
    pg_ctl = shutil.which("pg_ctl")
    return Path(os.path.realpath(pg_ctl)).parent if pg_ctl else None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresServer:
    """A running server (`postgres_server`): `url` of a fresh database per `new_database`."""

    def __init__(self, root: Path, port: int, runas: list[str]) -> None:
        self.root, self.port, self.runas = root, port, runas
        self.socket_dir = root / "sock"
        self._n = 0

    def url(self, database: str) -> str:
        return (f"postgresql://kinecal@/{database}?host={self.socket_dir}"
                f"&port={self.port}")

    def new_database(self, prefix: str = "t") -> str:
        """A new empty database; its URL."""
        import psycopg

        self._n += 1
        name = f"{prefix}{os.getpid()}_{self._n}"
        with psycopg.connect(host=str(self.socket_dir), port=self.port, user="kinecal",
                             dbname="postgres", autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)


@contextlib.contextmanager
def postgres_server() -> Iterator[PostgresServer]:
    """Start a server for the duration of the block (module docstring)."""
    bindir = bin_dir()
    if bindir is None:
        raise RuntimeError("PostgreSQL is not installed: run `bash .ci/install-postgres` as "
                           "root (or apt-get install postgresql), or make test")
    root = Path(tempfile.mkdtemp(prefix="kpg"))  # short: a socket path is <= 107 bytes
    runas: list[str] = []
    if os.geteuid() == 0:
        runas = ["runuser", "-u", "nobody", "--"]
        os.chmod(root, 0o755)
        shutil.chown(root, "nobody")
    (root / "sock").mkdir()
    if runas:
        shutil.chown(root / "sock", "nobody")
    data = root / "data"
    env = {**os.environ, "LC_ALL": "C", "TZ": "UTC"}
    subprocess.run([*runas, str(bindir / "initdb"), "-D", str(data), "-U", "kinecal",
                    "--auth=trust", "--no-sync", "-E", "UTF8"], check=True, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=root)
    port = _free_port()
    opts = (f"-k {root / 'sock'} -p {port} -c listen_addresses='' -c fsync=off "
            "-c full_page_writes=off -c synchronous_commit=off -c max_connections=60")
    subprocess.run([*runas, str(bindir / "pg_ctl"), "-D", str(data), "-o", opts, "-w",
                    "-t", "60", "-l", str(root / "log"), "start"], check=True, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=root)
    try:
        yield PostgresServer(root, port, runas)
    finally:
        subprocess.run([*runas, str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate",
                        "-w", "stop"], env=env, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, cwd=root)
        for _ in range(50):
            try:
                shutil.rmtree(root)
                break
            except OSError:
                time.sleep(0.1)
