"""``kinecal bench``: run the benchmark scripts of a source checkout.

The scripts (``benchmarks/bench_*.py``) compare kinecal with its peers in the same process
and print speed ratios and accuracy numbers. They are not installed with the package, so
this command needs a source checkout: it runs the ``benchmarks/`` folder of the checkout
the imported package comes from (``<checkout>/src/kinecal`` -> ``<checkout>/benchmarks``),
and nothing else. A ``benchmarks/`` folder in the current directory is never run: a
downloaded folder with a ``bench_*.py`` must not become code that ``kinecal bench`` runs.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.errors import InputError


def find_benchmarks() -> Path:
    """The ``benchmarks`` folder of the source checkout the package was imported from.

    The package must sit in ``<checkout>/src/kinecal`` beside ``<checkout>/pyproject.toml``
    and ``<checkout>/benchmarks``; the working directory plays no part.
    """
    import kinecal

    package = Path(kinecal.__file__).resolve().parent
    checkout = package.parents[1]
    folder = checkout / "benchmarks"
    if (package.parent.name == "src" and (checkout / "pyproject.toml").is_file()
            and folder.is_dir() and any(folder.glob("bench_*.py"))):
        return folder
    raise InputError(
        f"kinecal is installed from {package}, not from a source checkout: kinecal bench runs "
        "the benchmark scripts of a checkout (git clone the repository, pip install -e . and "
        "run it there)",
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
