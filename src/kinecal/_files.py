"""File helpers used by every layer: atomic writes and strict reads (YAML: `kinecal._yaml`).

Writes go to a temporary file in the target directory, then a rename: an existing output
is never half overwritten. Reads turn every failure into `kinecal.InputError` naming the
file. (This module sits beside `kinecal.errors`, below all layers.)

Temporary files are named ``.<name>.kinecal-<host>-<pid>.<random>.tmp`` (``<host>``: 8 hex
digits of a hash of the host name, ``<pid>``: the writing process). A write that is killed
before its rename (SIGKILL, power loss) leaves one behind; the next write into the same
folder removes every such file whose writer process is gone (same host) or that has not
been touched for `STALE_TEMP_SECONDS` (any host), so a killed 500 MB write does not stay
on the disk for good.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from kinecal.errors import InputError

__all__ = [
    "MAX_TEXT_BYTES",
    "STALE_TEMP_SECONDS",
    "atomic_open",
    "check_input_file",
    "probe_writable",
    "read_json",
    "read_text",
    "sweep_stale_temp_files",
    "write_bytes_atomic",
    "write_text_atomic",
]

#: a temporary file of another host (or of a recycled pid) untouched this long is stale
STALE_TEMP_SECONDS = 24 * 3600.0
#: largest text input (model, geometry, jobs, JSON, FileStorage YAML) read into memory
MAX_TEXT_BYTES = 256_000_000
#: the part of the target's name kept in a temporary name (names are limited to 255 bytes)
_NAME_KEEP = 100

_TEMP_RE = re.compile(r"^\..*\.kinecal-([0-9a-f]{8})-(\d+)\.[^.]+\.tmp$", re.DOTALL)
#: folders already swept by this process (a sweep lists the folder: once is enough)
_SWEPT: set[str] = set()
#: errors of the path itself (a user mistake, exit 2), as opposed to the disk (exit 1)
_PATH_ERRNOS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENAMETOOLONG, errno.ENOTDIR,
                errno.EISDIR, errno.ELOOP, errno.ENOENT}


#: errors of the disk (exit 1), not of the path
_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}


def _host_tag() -> str:
    import hashlib  # lazily: 4 ms of every command's start-up
    import socket

    return hashlib.sha1(socket.gethostname().encode("utf-8", "replace")).hexdigest()[:8]


def pid_alive(pid: int) -> bool:
    """Whether process `pid` exists (True when it cannot be probed: Windows, no permission)."""
    if os.name == "nt":  # os.kill(pid, 0) is not a probe there: rely on the age rule
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):  # exists, or cannot be probed
        return True
    return True


def sweep_stale_temp_files(folder: str | Path, *, now: float | None = None) -> list[Path]:
    """Remove kinecal's own stale temporary files in `folder`; return the removed paths.

    A temporary file (see the module docstring for the naming) is stale when it was
    written on this host by a process that no longer exists, or when it has not been
    modified for `STALE_TEMP_SECONDS`. Other files are never touched; errors (a file
    removed meanwhile, no permission) are ignored.
    """
    folder = Path(folder)
    now = time.time() if now is None else now
    host, removed = _host_tag(), []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        m = _TEMP_RE.match(entry.name)
        if m is None:
            continue
        try:
            st = entry.stat(follow_symlinks=False)
            if not stat.S_ISREG(st.st_mode):
                continue
            dead = m.group(1) == host and int(m.group(2)) != os.getpid() \
                and not pid_alive(int(m.group(2)))
            if dead or now - st.st_mtime > STALE_TEMP_SECONDS:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


def _sweep_once(folder: Path) -> None:
    key = os.path.abspath(folder)
    if key not in _SWEPT:
        _SWEPT.add(key)
        sweep_stale_temp_files(folder)


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


def probe_writable(path: str | Path) -> None:
    """Create and remove a temporary file beside `path`, as `atomic_open` will: the one
    sure test that the folder takes a new file (``/proc``, a read-only mount, a full
    inode table refuse it whatever the permission bits say). Devices and FIFOs, written in
    place, and missing folders are left to the writer.

    Raises
    ------
    InputError
        The folder refuses the file (with the reason).
    """
    path = Path(path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    try:
        if target.exists() and not target.is_file():
            return
    except OSError:
        return
    if not target.parent.is_dir():
        return
    prefix = f".{target.name[:_NAME_KEEP]}.kinecal-{_host_tag()}-{os.getpid()}."
    try:
        fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise InputError(f"cannot write here ({exc.strerror or exc})", file=path) from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(tmp)


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a temporary file next to `path`; rename it over `path` only on success.

    An exception inside the ``with`` block removes the temporary file and leaves any
    existing `path` untouched. A symbolic link is followed (the file it points to is
    replaced, the link stays); an existing target that is not a regular file (a device
    such as ``/dev/null``, a FIFO) is written directly, never replaced. An existing file
    without write permission is refused. Stale temporary files of earlier killed writes
    in the folder are removed first (`sweep_stale_temp_files`).
    """
    path = Path(path)
    if path.is_dir():
        raise InputError("is a directory; expected a file path to write", file=path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    binary = "b" in mode
    try:
        st = target.stat()
    except OSError:
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):  # /dev/null, a FIFO: no rename
        try:
            fh = open(target, mode, encoding=None if binary else encoding)
        except OSError as exc:
            raise _path_error(exc, path) from None
        try:
            with fh:
                yield fh
        except OSError as exc:  # /dev/full: name the file written
            raise _named(exc, path) from None
        return
    if st is not None and not os.access(target, os.W_OK):
        raise InputError("is read-only; refusing to replace it (change its permissions or "
                         "choose another output path)", file=path)
    if len(os.fsencode(target.name)) > 255:
        raise InputError("file name too long (at most 255 bytes)", file=path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        _sweep_once(target.parent)
        prefix = f".{target.name[:_NAME_KEEP]}.kinecal-{_host_tag()}-{os.getpid()}."
        fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=".tmp", dir=target.parent)
    except OSError as exc:  # parent is a file, no permission, read-only file system
        raise InputError(f"cannot write here ({exc.strerror or exc})", file=path) from None
    try:
        os.chmod(tmp, _file_mode(target))  # mkstemp makes 0600; a result file is 0644-like
        try:
            with os.fdopen(fd, mode, encoding=None if binary else encoding,
                           newline=None) as fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            raise _named(exc, path) from None
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
