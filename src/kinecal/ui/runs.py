"""Calibrations and other commands run from the page: the command line itself in a worker
process, so that the page never waits for one and a run is the CLI's to the byte.

A run is ``python -m kinecal ARGS`` in the working folder with ``KINECAL_PROGRESS=lines``
(`kinecal.cli._progress.progress` then writes its steps as lines on stderr); a thread reads
its stderr as it comes (progress, ``kinecal: warning:`` lines, the one ``kinecal: error:``
line of a refused input) and calls back on every change. Stopping a run ends its process
(the command line's clean-up runs: no half-written output).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Run"]

_PROGRESS = "kinecal: progress: "


@dataclass
class Run:
    """One command run in a worker process.

    Attributes
    ----------
    label : str
        Its name in the page (``run 1``).
    args : list of str
        The command line after ``kinecal``.
    folder : Path
        Where it writes its files.
    status : str
        ``waiting``, ``running``, ``done``, ``failed`` or ``stopped``.
    ok_codes : tuple of int
        Exit statuses of a run that did its work (``kinecal check`` exits 3 or 4 with its
        verdict); another status is a failure.
    """

    label: str
    args: list[str]
    folder: Path
    on_change: Callable[[Run], None] | None = None
    ok_codes: tuple[int, ...] = (0,)
    status: str = "waiting"
    task: str = ""
    done: int = 0
    total: int | None = None
    best: float | None = None
    warnings: list[str] = field(default_factory=list)
    error: str | None = None
    stdout: str = ""
    returncode: int | None = None
    started: float = 0.0
    seconds: float = 0.0
    _proc: subprocess.Popen | None = None
    _stopping: bool = False

    @property
    def command(self) -> str:
        """The command as the user would type it."""
        return " ".join(["kinecal", *(_quote(a) for a in self.args)])

    @property
    def running(self) -> bool:
        return self.status == "running"

    def start(self) -> Run:
        """Start the process and the thread that follows it."""
        env = {**os.environ, "KINECAL_PROGRESS": "lines", "PYTHONUNBUFFERED": "1"}
        self.folder.mkdir(parents=True, exist_ok=True)
        self.started = time.perf_counter()
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "kinecal", *self.args], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True, env=env,
            start_new_session=True)
        self.status = "running"
        self._changed()
        threading.Thread(target=self._follow, name=f"kinecal-ui-{self.label}",
                         daemon=True).start()
        return self

    def stop(self) -> None:
        """End the run's process (SIGTERM: the command line cleans up and exits 143)."""
        proc = self._proc
        if proc is not None and proc.poll() is None:
            self._stopping = True
            proc.send_signal(signal.SIGTERM)

    def wait(self, timeout: float | None = None) -> Run:
        """Block until the run has ended (for scripts and tests; the page never waits)."""
        end = None if timeout is None else time.monotonic() + timeout
        while self.status in ("waiting", "running"):
            if end is not None and time.monotonic() > end:
                raise TimeoutError(f"{self.label} still running after {timeout} s")
            time.sleep(0.02)
        return self

    def _changed(self) -> None:
        self.seconds = time.perf_counter() - self.started
        if self.on_change is not None:
            self.on_change(self)

    def _follow(self) -> None:
        proc = self._proc
        assert proc is not None and proc.stderr is not None and proc.stdout is not None
        out: list[str] = []
        reader = threading.Thread(target=lambda: out.append(proc.stdout.read()), daemon=True)
        reader.start()
        for line in proc.stderr:
            self._line(line.rstrip("\n"))
        reader.join()
        self.returncode = proc.wait()
        self.stdout = "".join(out)
        self.status = ("stopped" if self._stopping else
                       "done" if self.returncode in self.ok_codes else "failed")
        if self.returncode not in (0, 2) and self.error is None and self.status == "failed":
            self.error = f"kinecal exited with status {self.returncode}"
        self._changed()

    def _line(self, line: str) -> None:
        if line.startswith(_PROGRESS):
            try:
                step = json.loads(line[len(_PROGRESS):])
            except ValueError:
                return
            self.task = step.get("task", self.task)
            self.done, self.total = int(step.get("done", 0)), step.get("total")
            self.best = step.get("best")
        elif line.startswith("kinecal: warning: "):
            self.warnings.append(line)
        elif line.startswith("kinecal: error: ") or line.startswith("kinecal: internal error"):
            self.error = line
        else:
            return
        self._changed()


def _quote(arg: str) -> str:
    import shlex

    return shlex.quote(arg)


def calibrate_args(model: str, data: Sequence[str], validate: Sequence[str],
                   folder: Path, method: str = "lm", extra: Sequence[str] = ()) -> list[str]:
    """The ``kinecal calibrate`` command line of a run writing into `folder`."""
    args = ["calibrate", model, *data]
    for v in validate:
        args += ["--validate", v]
    args += ["--method", method, "--out", str(folder / "result.json"),
             "--report", str(folder / "report.html"), *extra]
    return args
