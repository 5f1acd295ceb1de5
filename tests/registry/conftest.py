"""Fixtures of the registry's tests: a real PostgreSQL server (one per session, a fresh
database per test; tests/registry/pgserver.py), the ``db`` fixture parametrised over both
backends, a calibrated UR5 with its truth, and the command line run in this process."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, HERE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


pgserver = _load("pgserver")


@pytest.fixture(scope="session")
def postgres():
    """The session's PostgreSQL server (started from Debian's binaries)."""
    if pgserver.bin_dir() is None:
        pytest.fail("PostgreSQL is not installed: run `bash .ci/install-postgres` as root "
                    "(apt-get install postgresql), or make test")
    with pgserver.postgres_server() as server:
        yield server


@pytest.fixture(params=["sqlite", "postgresql"])
def db(request, tmp_path):
    """A new, empty registry of each backend: an SQLite path or a PostgreSQL URL."""
    if request.param == "sqlite":
        return str(tmp_path / "kinecal.db")
    return request.getfixturevalue("postgres").new_database()


@pytest.fixture
def sqlite_db(tmp_path):
    return str(tmp_path / "kinecal.db")


def run_cli(*args: str, cwd: Path | None = None) -> tuple[int, str, str]:
    """``kinecal ARGS`` in this process: (status, stdout, stderr)."""
    from kinecal.cli import main

    out, err = io.StringIO(), io.StringIO()
    old = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main([str(a) for a in args])
    finally:
        os.chdir(old)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def cli():
    return run_cli


class Arm:
    """A simulated UR5: its truth, a calibration result file, check poses."""

    def __init__(self, root: Path) -> None:
        import kinecal
        from kinecal.calibration.serial.simulate import simulate
        from kinecal.registry.plan import plan_check

        self.model = kinecal.load_model("ur5")
        sim = simulate(self.model, 40, errors="random", noise=0.03, rng=7)
        self.truth = sim.true_params
        res = kinecal.calibrate(self.model, sim.data)
        self.result = root / "ur5-cal.json"
        self.result.write_text(json.dumps(res.to_dict()), encoding="utf-8")
        self.q = plan_check(self.model, 10, seed=3).q
        self.root = root

    def measure(self, name: str, params=None, noise: float = 0.03, seed: int = 0,
                q=None) -> Path:
        """Tracker CSV of the arm (`params`, default its truth) at the check poses."""
        q = self.q if q is None else q
        p = self.truth if params is None else params
        xyz = self.model.positions(q, p) + np.random.default_rng(seed).normal(0, noise,
                                                                             (len(q), 3))
        deg = np.degrees(q)
        path = self.root / name
        cols = [f"q{i}" for i in range(1, 7)] + ["x", "y", "z"]
        rows = [",".join(repr(float(v)) for v in (*a, *b)) for a, b in zip(deg, xyz,
                                                                          strict=True)]
        path.write_text(",".join(cols) + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
        return path

    def shifted(self, name: str, value: float) -> np.ndarray:
        """The truth with parameter `name` changed by `value` (API units)."""
        p = self.truth.copy()
        p[self.model.index([name])[0]] += value
        return p


@pytest.fixture(scope="session")
def arm(tmp_path_factory):
    return Arm(tmp_path_factory.mktemp("arm"))
