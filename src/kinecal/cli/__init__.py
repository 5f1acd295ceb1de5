"""The ``kinecal`` command line.

Every command lives in a module of this package that registers itself on the shared
typer app. The error contract (DESIGN section 4): a user mistake prints one line on
stderr and exits 2; an internal error exits 1 (traceback only with KINECAL_DEBUG=1).
"""

from __future__ import annotations

import os

# kinecal's matrices are small (thousands x tens): a multi-threaded BLAS only adds
# contention there (a 3000 x 33 QR: 3 ms on one thread, 45-185 ms on two busy cores).
# Set before numpy loads; an explicit user setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import importlib  # noqa: E402
import sys  # noqa: E402

import click  # noqa: E402

from kinecal.cli._app import app  # noqa: E402

try:  # typer >= 0.20 ships its own copy of click; catch its exceptions as well as click's
    from typer._click import exceptions as _tclick
except ImportError:  # pragma: no cover - older typer uses click itself
    _tclick = click.exceptions
import typer.exceptions as _texc  # noqa: E402

from kinecal.errors import InputError  # noqa: E402

# typer 0.29's bundled click has no Exit/Abort (they live in typer.exceptions): gather the
# classes that exist, or the except clauses below raise AttributeError on any exception.
_EXIT = tuple({c for c in (click.exceptions.Exit, getattr(_tclick, "Exit", None),
                           getattr(_texc, "Exit", None)) if c is not None})
_ABORT = tuple({c for c in (click.exceptions.Abort, getattr(_tclick, "Abort", None),
                            getattr(_texc, "Abort", None)) if c is not None})

__all__ = ["app", "main"]

# One module per command family; each registers its commands on `app` when imported.
_COMMAND_MODULES = [
    "kinecal.cli.serial",
    "kinecal.cli.reproduce",
    "kinecal.cli.handeye",
    "kinecal.cli.stewart",
    "kinecal.cli.batch",
    "kinecal.cli.demo",
    "kinecal.cli.bench",
]


def _load_commands() -> None:
    for name in _COMMAND_MODULES:
        importlib.import_module(name)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return (and exit with) the status code."""
    _load_commands()
    args = sys.argv[1:] if argv is None else list(argv)
    try:
        rv = app(args=args, prog_name="kinecal", standalone_mode=False)
        code = rv if isinstance(rv, int) else 0
    except InputError as exc:
        sys.stderr.write(f"kinecal: error: {exc.one_line()}\n")
        code = 2
    except (click.exceptions.NoArgsIsHelpError, _tclick.NoArgsIsHelpError):
        code = 0
    except (click.UsageError, _tclick.UsageError) as exc:
        where = f"{exc.ctx.command_path}: " if exc.ctx is not None else ""
        sys.stderr.write(f"kinecal: error: {where}{' '.join(exc.format_message().split())}\n")
        code = 2
    except _EXIT as exc:
        code = exc.exit_code
    except _ABORT:
        sys.stderr.write("kinecal: aborted\n")
        code = 130
    except (click.ClickException, _tclick.ClickException) as exc:
        sys.stderr.write(f"kinecal: error: {' '.join(exc.format_message().split())}\n")
        code = 2
    except KeyboardInterrupt:
        sys.stderr.write("kinecal: interrupted\n")
        code = 130
    except BrokenPipeError:
        code = 0
    except Exception as exc:
        if os.environ.get("KINECAL_DEBUG"):
            raise
        sys.stderr.write(
            f"kinecal: internal error: {type(exc).__name__}: {exc} "
            "(set KINECAL_DEBUG=1 for a traceback)\n"
        )
        code = 1
    if argv is None:
        sys.exit(code)
    return code
