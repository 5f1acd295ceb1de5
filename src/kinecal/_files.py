"""File helpers used by every layer: atomic writes and strict reads (YAML: `kinecal._yaml`).

Writes go to a temporary file in the target directory, then a rename: an existing output
is never half overwritten. Reads turn every failure into `kinecal.InputError` naming the
file. (This module sits beside `kinecal.errors`, below all layers.)

A write killed before its rename leaves its temporary file; the next write into the same
folder removes it (`kinecal._temps`). `all_or_nothing` commits the several files of one
command together.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from kinecal._temps import remove_own_temp_files, sweep_once, temp_prefix
from kinecal.errors import InputError

__all__ = [
    "MAX_TEXT_BYTES",
    "all_or_nothing",
    "atomic_open",
    "check_input_file",
    "probe_writable",
    "read_json",
    "read_text",
    "write_bytes_atomic",
    "write_text_atomic",
    "written_in_place",
]

#: largest text input (model, geometry, jobs, JSON, FileStorage YAML) read into memory
MAX_TEXT_BYTES = 256_000_000
#: errors of the path itself (a user mistake, exit 2), as opposed to the disk (exit 1)
_PATH_ERRNOS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENAMETOOLONG, errno.ENOTDIR,
                errno.EISDIR, errno.ELOOP, errno.ENOENT}


#: errors of the disk (exit 1), not of the path
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


def _path_error(exc: OSError, path: Path) -> Exception:
    """`InputError` for a problem of the path (permissions, name), else `exc` itself."""
    if exc.errno in _PATH_ERRNOS:
        return InputError(f"cannot write here ({exc.strerror or exc})", file=path)
    return exc


def _named(exc: OSError, path: Path) -> OSError:
    """A disk error (no space, quota, I/O) of a write that names the file written."""
    if exc.errno in _DISK_ERRNOS and exc.filename is None:
        return OSError(exc.errno, exc.strerror or str(exc), str(path))
    return exc


def _open_fd(path: Path) -> int | None:
    """The descriptor behind `path` when it names one of this process's open files
    (``/dev/stdout``, ``/dev/stderr``, ``/dev/fd/N``, ``/proc/self/fd/N``): the output the
    shell redirected, written through that descriptor (a pipe, a terminal, a file opened
    for appending), never replaced. None for any other path."""
    names = {"/dev/stdout": 1, "/dev/stderr": 2}
    text = os.path.abspath(path)
    for _ in range(8):  # /dev/stdout -> /proc/self/fd/1 -> ...
        if text in names:
            return names[text]
        for prefix in ("/dev/fd/", "/proc/self/fd/", f"/proc/{os.getpid()}/fd/"):
            if text.startswith(prefix) and text[len(prefix):].isdigit():
                return int(text[len(prefix):])
        try:
            link = os.readlink(text)
        except OSError:
            return None
        text = os.path.normpath(os.path.join(os.path.dirname(text), link))
    return None


def written_in_place(path: str | Path) -> bool:
    """True when a write to `path` goes into it directly rather than by a rename: an open
    descriptor (`_open_fd`), a device (``/dev/null``), a FIFO."""
    if _open_fd(Path(path)) is not None:
        return True
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def probe_writable(path: str | Path) -> None:
    """Create and remove a temporary file beside `path`, as `atomic_open` will: the one
    sure test that the folder takes a new file (``/proc``, a read-only mount, a full
    inode table refuse it whatever the permission bits say). Devices, FIFOs and open
    descriptors, written in place, and missing folders are left to the writer.

    Raises
    ------
    InputError
        The folder refuses the file (with the reason).
    """
    path = Path(path)
    if written_in_place(path):
        return
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    if not target.parent.is_dir():
        return
    with _signals_held():  # Ctrl-C between the creation and the removal would leave it
        try:
            fd, tmp = tempfile.mkstemp(prefix=temp_prefix(target), suffix=".tmp",
                                       dir=target.parent)
        except OSError as exc:
            raise InputError(f"cannot write here ({exc.strerror or exc})", file=path) from None
        os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)


#: the writes of the open `all_or_nothing` block: target -> its finished temporary file
_PENDING: dict[Path, str] | None = None
#: the folders the open block writes into (cleaned of this process's temporary files when
#: the block fails, even one whose writer was interrupted before it could remove it)
_FOLDERS: set[Path] = set()


@contextlib.contextmanager
def all_or_nothing() -> Iterator[None]:
    """Commit every `atomic_open` write of the block together, or none of them.

    Inside the block each file is written, flushed and synced to its temporary file as
    usual, but not yet renamed; when the block ends normally every temporary file is
    renamed over its target (with Ctrl-C, SIGTERM and SIGHUP held back for those few
    renames). When the block ends by an exception (a disk full while the report is
    written, Ctrl-C while a PDF is rendered, a ``ulimit -f`` exceeded), every temporary
    file is removed and no earlier output is replaced: a command's result JSON, model and
    report are either all new or all as they were. Writes in place (`written_in_place`:
    ``/dev/stdout``, a device, a FIFO) cannot wait and are made at once. Blocks nest: the
    outermost one commits.
    """
    global _PENDING
    if _PENDING is not None:
        yield
        return
    _PENDING = pending = {}
    _FOLDERS.clear()
    try:
        yield
    except BaseException:
        _discard(pending)
        for folder in _FOLDERS:
            remove_own_temp_files(folder)
        raise
    finally:
        _PENDING = None
    _commit(pending)


def _discard(pending: dict[Path, str]) -> None:
    for tmp in pending.values():
        with contextlib.suppress(OSError):
            os.unlink(tmp)
    pending.clear()


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Ctrl-C, SIGTERM and SIGHUP held back (delivered at the end) for a few system calls
    that must not be cut apart (POSIX, main thread; elsewhere nothing is held)."""
    import signal
    import threading

    if not hasattr(signal, "pthread_sigmask") or \
            threading.current_thread() is not threading.main_thread():
        yield
        return
    held = [getattr(signal, s) for s in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, s)]
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _commit(pending: dict[Path, str]) -> None:
    """Rename every finished temporary file over its target, signals held back meanwhile."""
    with _signals_held():
        try:
            for target in list(pending):
                try:
                    os.replace(pending[target], target)
                except OSError as exc:
                    raise _path_error(exc, target) from None
                del pending[target]
        finally:
            _discard(pending)


@contextlib.contextmanager
def _in_place(path: Path, target: Path, fd: int | None, mode: str,
              encoding: str | None) -> Iterator[IO]:
    """Write a device, a FIFO or an open descriptor (`fd`) directly."""
    try:
        if fd is not None:  # the redirected output: its own descriptor, not a reopening
            fh = os.fdopen(os.dup(fd), mode, encoding=encoding)
        else:
            fh = open(target, mode, encoding=encoding)
    except OSError as exc:
        raise _path_error(exc, path) from None
    try:
        with fh:
            yield fh
    except OSError as exc:  # /dev/full: name the file written
        raise _named(exc, path) from None


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a temporary file next to `path`; rename it over `path` only on success.

    An exception inside the ``with`` block removes the temporary file and leaves any
    existing `path` untouched. A symbolic link is followed (the file it points to is
    replaced, the link stays); an existing target that is not a regular file (a device
    such as ``/dev/null``, a FIFO) and an open descriptor (``/dev/stdout``, written through
    the descriptor the shell redirected) are written directly, never replaced. An existing
    file without write permission is refused. Stale temporary files of earlier killed
    writes in the folder are removed first (`sweep_stale_temp_files`). Inside an
    `all_or_nothing` block the rename waits for the end of the block.
    """
    path = Path(path)
    encoding = None if "b" in mode else encoding
    fd = _open_fd(path)
    if fd is None and path.is_dir():
        raise InputError("is a directory; expected a file path to write", file=path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        st = target.stat()
    except OSError:
        st = None
    if fd is not None or (st is not None and not stat.S_ISREG(st.st_mode)):
        with _in_place(path, target, fd, mode, encoding) as fh:
            yield fh
        return
    if st is not None and not os.access(target, os.W_OK):
        raise InputError("is read-only; refusing to replace it (change its permissions or "
                         "choose another output path)", file=path)
    if len(os.fsencode(target.name)) > 255:
        raise InputError("file name too long (at most 255 bytes)", file=path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        sweep_once(target.parent)
        if _PENDING is not None:
            _FOLDERS.add(target.parent)
        fd, tmp = tempfile.mkstemp(prefix=temp_prefix(target), suffix=".tmp", dir=target.parent)
    except OSError as exc:  # parent is a file, no permission, read-only file system
        raise InputError(f"cannot write here ({exc.strerror or exc})", file=path) from None
    try:
        os.chmod(tmp, _file_mode(target))  # mkstemp makes 0600; a result file is 0644-like
        try:
            with os.fdopen(fd, mode, encoding=encoding, newline=None) as fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            raise _named(exc, path) from None
        if _PENDING is not None:  # all_or_nothing: renamed with the others at its end
            old = _PENDING.pop(target, None)
            _PENDING[target] = tmp
            if old is not None:
                with contextlib.suppress(OSError):
                    os.unlink(old)
            return
        try:
            os.replace(tmp, target)
        except OSError as exc:
            raise _path_error(exc, path) from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _file_mode(path: Path) -> int:
    """Mode of the existing `path`, else what ``open()`` would give under the umask."""
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write `text` to `path` atomically (UTF-8)."""
    with atomic_open(path, "w") as fh:
        fh.write(text)


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write `data` to `path` atomically."""
    with atomic_open(path, "wb", encoding=None) as fh:
        fh.write(data)


def check_input_file(path: str | Path, what: str = "a file") -> None:
    """Refuse a device as an input (``/dev/zero``, ``/dev/urandom``: endless data).

    Regular files, pipes and ``/dev/stdin`` redirected from a file or a pipe pass; a
    missing path passes too (its reader reports it).

    Raises
    ------
    InputError
        `path` is a character or block device.
    """
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        raise InputError(f"is a device, expected {what}", file=path)


def read_text(path: str | Path, max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of `path`; `InputError` (with the file) when missing or unreadable.

    Model, geometry, jobs, JSON and FileStorage files are small: more than `max_bytes`
    (a file, or a pipe that does not end) is refused rather than read into memory.
    """
    path = Path(path)
    check_input_file(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except FileNotFoundError:
        raise InputError("file not found", file=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a file", file=path) from None
    except OSError as exc:
        raise InputError(f"not a readable text file ({exc.strerror or exc})",
                         file=path) from None
    if len(data) > max_bytes:
        raise InputError(f"more than {max_bytes / 1e6:.0f} MB: too large for a model, jobs, "
                         "JSON or YAML file", file=path)
    try:
        return data.decode("utf-8-sig")  # a byte-order mark (Windows editors) is no content
    except UnicodeDecodeError as exc:
        raise InputError(f"not a readable text file ({exc})", file=path) from None


def read_json(path: str | Path) -> Any:
    """The JSON document in `path`; `InputError` naming the file (and line) otherwise."""
    text = read_text(path)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON at line {exc.lineno}: {exc.msg}", file=path) from None
    except ValueError:  # Python refuses integers of more than 4300 digits
        raise InputError("not valid JSON: a number of thousands of digits", file=path) from None
    except RecursionError:
        raise InputError("not valid JSON: nested too deeply", file=path) from None
