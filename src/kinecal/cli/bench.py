"""``kinecal bench``: run the benchmark scripts of a source checkout.

The scripts (``benchmarks/bench_*.py``) compare kinecal with its peers in the same process
and print speed ratios and accuracy numbers. They are not installed with the package, so
this command needs a source checkout: it looks for ``benchmarks/`` in the current
directory, then next to the source tree the package was imported from.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.errors import InputError


def find_benchmarks(start: Path | None = None) -> Path:
    """The ``benchmarks`` folder of the source checkout.

    Looks in `start` (default: the working directory), then in the checkout that holds
    the imported package (``src/kinecal`` -> ``benchmarks``).
    """
    import kinecal

    candidates = [(start or Path.cwd()) / "benchmarks",
                  Path(kinecal.__file__).resolve().parents[2] / "benchmarks"]
    for folder in candidates:
        if folder.is_dir() and any(folder.glob("bench_*.py")):
            return folder
    raise InputError(
        "no benchmarks/bench_*.py here: kinecal bench runs the benchmark scripts of a source "
        "checkout (git clone the repository and run it from there)",
        option="bench",
    )


@app.command()
def bench(
    quick: bool = typer.Option(False, "--quick", help="Pass --quick to every script "
                               "(seconds instead of minutes)."),
    only: str | None = typer.Option(None, "--only", help="Comma-separated script names "
                                    "(e.g. fk,handeye) instead of all of them."),
) -> int:
    """Run benchmarks/bench_*.py of a source checkout and print their output."""
    folder = find_benchmarks()
    scripts = sorted(folder.glob("bench_*.py"))
    if only is not None:
        wanted = {w.strip().removeprefix("bench_").removesuffix(".py")
                  for w in only.split(",") if w.strip()}
        names = {s.stem.removeprefix("bench_") for s in scripts}
        unknown = sorted(wanted - names)
        if unknown or not wanted:
            raise InputError(f"unknown benchmark {', '.join(unknown) or '(empty)'}; expected "
                             f"one of {', '.join(sorted(names))}", option="--only")
        scripts = [s for s in scripts if s.stem.removeprefix("bench_") in wanted]
    failed = []
    env = dict(os.environ)
    for script in scripts:
        cmd = [sys.executable, str(script)] + (["--quick"] if quick else [])
        typer.echo(f"== {script.name}{' --quick' if quick else ''}")
        sys.stdout.flush()
        proc = subprocess.run(cmd, cwd=folder.parent, env=env, check=False)
        if proc.returncode != 0:
            failed.append(f"{script.name} (exit {proc.returncode})")
        typer.echo("")
    if failed:
        sys.stderr.write(f"kinecal: benchmark failed: {', '.join(failed)}\n")
        return 1
    typer.echo(f"{len(scripts)} benchmarks ran")
    return 0
