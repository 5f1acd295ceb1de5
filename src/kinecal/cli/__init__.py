"""The ``kinecal`` command line.

Every command lives in a module of this package that registers itself on the shared
typer app. The error contract (DESIGN section 4): a user mistake prints one line on
stderr and exits 2; an internal error exits 1 (traceback only with KINECAL_DEBUG=1);
Ctrl-C exits 130 and SIGTERM / SIGHUP 143, each after the same clean-up (no temporary
file left, the batch summary written).
"""

from __future__ import annotations

import os

from kinecal import _blas

# kinecal's matrices are small (thousands x tens): a multi-threaded BLAS only adds
# contention there (a 3000 x 33 QR: 3 ms on one thread, 45-185 ms on two busy cores).
# Set before numpy loads (then no thread limit is needed later); an explicit user setting
# wins.
_blas.pin_environment()
# OpenCV's own warnings (an image file it reads in part) would land on stderr beside the
# one-line contract; kinecal says what it rejects and why. Set before cv2 loads.
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

import contextlib  # noqa: E402
import errno  # noqa: E402
import importlib  # noqa: E402
import sys  # noqa: E402
import warnings  # noqa: E402

from kinecal.cli._signals import Terminated, terminate_like_interrupt  # noqa: E402
from kinecal.errors import InputError  # noqa: E402


def _exception_types(name: str) -> tuple[type[BaseException], ...]:
    """Every class called `name` in click, typer's bundled click and typer.exceptions.

    typer >= 0.20 ships its own copy of click (``typer._click``) and no longer installs
    click, whose Exit/Abort moved to ``typer.exceptions``: a plain ``import click`` fails
    on a clean install, so each module is optional here.
    """
    found = []
    for module in ("click.exceptions", "typer._click.exceptions", "typer.exceptions"):
        if module == "click.exceptions" and "click" not in sys.modules:
            continue  # typer did not import click (it bundles its own): nothing raises it
        try:
            cls = getattr(importlib.import_module(module), name, None)
        except ImportError:
            continue
        if isinstance(cls, type) and cls not in found:
            found.append(cls)
    return tuple(found)


def _types(name: str) -> tuple[type[BaseException], ...]:
    """`_exception_types` of `name`, looked up once an exception is being matched (a
    command run without typer never imports it: `kinecal.cli._direct`)."""
    found = _TYPES.get(name)
    if found is None:
        import typer  # noqa: F401  (its exception modules)

        found = _TYPES[name] = _exception_types(name)
    return found


_TYPES: dict[str, tuple[type[BaseException], ...]] = {}


def __getattr__(name: str):
    if name == "app":  # the typer application, built on first use
        from kinecal.cli._app import app

        return app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["app", "main"]

# One module per command family; each registers its commands on `app` when imported.
_COMMAND_MODULES = [
    "kinecal.cli.fk",
    "kinecal.cli.simulate",
    "kinecal.cli.identifiability",
    "kinecal.cli.calibrate",
    "kinecal.cli.reproduce",
    "kinecal.cli.handeye",
    "kinecal.cli.handeye_images",
    "kinecal.cli.stewart",
    "kinecal.cli.batch",
    "kinecal.cli.demo",
    "kinecal.cli.bench",
    "kinecal.cli.export",
    "kinecal.cli.compensate",
    "kinecal.cli.import_cmd",
    "kinecal.cli.iso9283",
    "kinecal.cli.datasets",
    "kinecal.cli.registry",
    "kinecal.cli.check",
    "kinecal.cli.ui",
]


#: the module of each command: ``kinecal CMD ...`` imports that module alone (its
#: imports, and typer's building of the other commands' options, cost more than most
#: commands' own work); anything else (``--help``, an unknown name) loads every module.
#: tests/cli/test_cli_startup.py checks this table against the registered commands.
_COMMANDS = {
    "models": "kinecal.cli.fk",
    "fk": "kinecal.cli.fk",
    "simulate": "kinecal.cli.simulate",
    "select-poses": "kinecal.cli.calibrate",
    "identifiability": "kinecal.cli.identifiability",
    "calibrate": "kinecal.cli.calibrate",
    "reproduce": "kinecal.cli.reproduce",
    "handeye": "kinecal.cli.handeye",
    "handeye-poses": "kinecal.cli.handeye",
    "handeye-images": "kinecal.cli.handeye_images",
    "stewart": "kinecal.cli.stewart",
    "batch": "kinecal.cli.batch",
    "demo": "kinecal.cli.demo",
    "bench": "kinecal.cli.bench",
    "export": "kinecal.cli.export",
    "compensate": "kinecal.cli.compensate",
    "import": "kinecal.cli.import_cmd",
    "iso9283": "kinecal.cli.iso9283",
    "datasets": "kinecal.cli.datasets",
    "registry": "kinecal.cli.registry",
    "check": "kinecal.cli.check",
    "plan-check": "kinecal.cli.check",
    "ui": "kinecal.cli.ui",
}


def _load_commands(args: list[str] | None = None) -> None:
    """Import the command modules: the one of ``args[0]`` if known, else all of them."""
    if args and args[0] == "--version":  # printed by the app's callback: no command needed
        return
    module = _COMMANDS.get(args[0]) if args else None
    for name in [module] if module is not None else _COMMAND_MODULES:
        importlib.import_module(name)


def _run(args: list[str], direct: tuple | None = None) -> int:
    """Run the command of `args`: by typer, or `direct` (`kinecal.cli._direct.parse`)."""
    # numpy's floating-point RuntimeWarnings (overflow in absurd inputs) would print
    # source lines on stderr: kinecal checks its inputs and results itself
    with warnings.catch_warnings(), terminate_like_interrupt():
        warnings.simplefilter("ignore", RuntimeWarning)
        if direct is not None:
            from kinecal.cli._direct import run

            rv = run(*direct)
        else:
            from kinecal.cli._app import app

            rv = app(args=args, prog_name="kinecal", standalone_mode=False)
    return rv if isinstance(rv, int) else 0


#: errors of a path itself (exit 2), unlike those of the disk (no space: exit 1)
_PATH_ERRNOS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENAMETOOLONG, errno.ENOTDIR,
                errno.EISDIR, errno.ELOOP, errno.ENOENT, errno.EEXIST}


#: errors of the disk: exit 1, one line naming the file
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


def _drop_stdout() -> None:
    """Point the standard output at the null device once writing it failed: the data left
    in its buffer would fail again at exit ("Exception ignored", status 120)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def _internal_error(exc: BaseException) -> int:
    if os.environ.get("KINECAL_DEBUG"):
        raise exc
    sys.stderr.write(f"kinecal: internal error: {type(exc).__name__}: "
                     f"{' '.join(str(exc).split())} (set KINECAL_DEBUG=1 for a traceback)\n")
    return 1


def _check_source_date_epoch() -> None:
    """Refuse a malformed ``SOURCE_DATE_EPOCH`` before any library reads it; an empty one
    counts as unset (and is removed, as numpy's f2py would fail on it)."""
    if not os.environ["SOURCE_DATE_EPOCH"].strip():
        del os.environ["SOURCE_DATE_EPOCH"]
        return
    from kinecal._reproducible import source_date_epoch

    source_date_epoch()


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; return (and exit with) the status code."""
    args = sys.argv[1:] if argv is None else list(argv)
    from kinecal.cli import _common

    _common.COMMAND_LINE = ["kinecal", *args]  # for the record of a report
    from kinecal.cli._direct import parse

    direct = parse(args)  # plain arguments of a command run without typer, or None
    if direct is None:
        _load_commands(args)
    try:
        if "SOURCE_DATE_EPOCH" in os.environ:
            # checked first: numpy's f2py (imported by scipy.linalg) reads it with int()
            _check_source_date_epoch()
        code = _run(args, direct)
        sys.stdout.flush()  # a full disk or a closed pipe on stdout shows here, not at exit
        if code == 130:  # typer turns Ctrl-C into Exit(130), returned without a word
            sys.stderr.write("kinecal: interrupted\n")
        elif code == 143:
            sys.stderr.write("kinecal: terminated\n")
    except InputError as exc:
        sys.stderr.write(f"kinecal: error: {exc.one_line()}\n")
        code = 2
    except _types("NoArgsIsHelpError"):
        code = 0
    except _types("UsageError") as exc:
        where = f"{exc.ctx.command_path}: " if exc.ctx is not None else ""
        sys.stderr.write(f"kinecal: error: {where}{' '.join(exc.format_message().split())}\n")
        code = 2
    except _types("Exit") as exc:
        code = exc.exit_code
    except _types("Abort"):
        sys.stderr.write("kinecal: aborted\n")
        code = 130
    except _types("ClickException") as exc:
        sys.stderr.write(f"kinecal: error: {' '.join(exc.format_message().split())}\n")
        code = 2
    except Terminated:
        sys.stderr.write("kinecal: terminated\n")
        code = 143
    except KeyboardInterrupt:
        sys.stderr.write("kinecal: interrupted\n")
        code = 130
    except BrokenPipeError:
        _drop_stdout()
        code = 0
    except SystemExit as exc:  # typer ends a broken stdout pipe (`kinecal ... | head`) with 1
        if type(sys.stdout).__name__ != "PacifyFlushWrapper":
            raise
        code = 0 if exc.code == 1 else exc.code
    except OSError as exc:
        if exc.errno in _DISK_ERRNOS:  # the disk, not kinecal nor the input: exit 1
            # files are named by their writer (kinecal._files.atomic_open): an unnamed
            # write is the standard output's (kinecal fk ... > /dev/full)
            where = f"{os.fsdecode(exc.filename)}: " if exc.filename else "standard output: "
            if not exc.filename:
                _drop_stdout()
            sys.stderr.write(f"kinecal: error: {where}{exc.strerror or exc} (nothing was "
                             "replaced; free space and run again)\n")
            code = 1
        elif exc.errno not in _PATH_ERRNOS or exc.filename is None:
            code = _internal_error(exc)
        else:  # a path the user gave cannot be used as such (too long, no permission...)
            sys.stderr.write(f"kinecal: error: {os.fsdecode(exc.filename)}: "
                             f"{exc.strerror or exc}\n")
            code = 2
    except Exception as exc:
        code = _internal_error(exc)
    if argv is None:
        sys.exit(code)
    return code
