"""kinecal's temporary files: their names, and the sweep of those a killed write left.

Temporary files are named ``.<name>.kinecal-<host>-<pid>.<random>.tmp`` (``<host>``: 8 hex
digits of a hash of the host name, ``<pid>``: the writing process). A write that is killed
before its rename (SIGKILL, power loss) leaves one behind; the next write into the same
folder removes every such file whose writer process is gone (same host) or that has not
been touched for `STALE_TEMP_SECONDS` (any host), so a killed 500 MB write does not stay
on the disk for good. (This module sits beside `kinecal._files`, below all layers.)
"""

from __future__ import annotations

import os
import re
import stat
import time
from pathlib import Path

__all__ = ["STALE_TEMP_SECONDS", "host_tag", "pid_alive", "remove_own_temp_files",
           "sweep_once", "sweep_stale_temp_files", "temp_prefix"]

#: a temporary file of another host (or of a recycled pid) untouched this long is stale
STALE_TEMP_SECONDS = 24 * 3600.0
#: the part of the target's name kept in a temporary name (names are limited to 255 bytes)
_NAME_KEEP = 100

_TEMP_RE = re.compile(r"^\..*\.kinecal-([0-9a-f]{8})-(\d+)\.[^.]+\.tmp$", re.DOTALL)
#: folders already swept by this process (a sweep lists the folder: once is enough)
_SWEPT: set[str] = set()


def temp_prefix(target: Path) -> str:
    """The start of the name of a temporary file written for `target` (``mkstemp`` adds
    the random part and ``.tmp``)."""
    return f".{target.name[:_NAME_KEEP]}.kinecal-{host_tag()}-{os.getpid()}."


def host_tag() -> str:
    """8 hex digits of a hash of the host name (the ``<host>`` of a temporary name)."""
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
    host, removed = host_tag(), []
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


def sweep_once(folder: Path) -> None:
    """`sweep_stale_temp_files` of `folder`, once per process."""
    key = os.path.abspath(folder)
    if key not in _SWEPT:
        _SWEPT.add(key)
        sweep_stale_temp_files(folder)


def remove_own_temp_files(folder: Path) -> None:
    """Remove this process's temporary files in `folder` (an interrupted group of writes:
    Ctrl-C may land between a temporary file's creation and its writer's clean-up)."""
    host, pid = host_tag(), str(os.getpid())
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return
    for entry in entries:
        m = _TEMP_RE.match(entry.name)
        if m is not None and m.group(1) == host and m.group(2) == pid:
            try:
                os.unlink(entry.path)
            except OSError:
                continue
