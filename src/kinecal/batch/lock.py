"""One batch at a time per output folder.

Two ``kinecal batch ... --out DIR`` started together both found no result in ``DIR`` and
both ran every job. `folder_lock` holds an exclusive advisory lock (``flock``) on
``DIR/.kinecal-batch.lock`` for the whole run; a second run into the same folder is
refused at once, naming the process that holds it. The kernel releases the lock when its
holder ends, however it ends (SIGKILL included): no stale lock is ever left behind. (Where
``fcntl`` does not exist, Windows, runs are not locked.)
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from kinecal.errors import InputError

__all__ = ["LOCK_NAME", "folder_lock"]

LOCK_NAME = ".kinecal-batch.lock"


@contextlib.contextmanager
def folder_lock(folder: str | Path) -> Iterator[None]:
    """Hold the batch lock of `folder` (an existing directory) inside the block.

    Raises
    ------
    InputError
        Another process holds it (its pid named when it wrote it).
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not on POSIX
        yield
        return
    path = Path(folder) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise InputError(f"cannot create the batch lock ({exc.strerror or exc})",
                         file=path) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
            who = f" (pid {holder})" if holder.isdigit() else ""
            raise InputError(f"another kinecal batch{who} is writing into {folder}: wait for "
                             "it to end (a rerun then resumes from its results) or choose "
                             "another --out", option="--out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        yield
    finally:
        os.close(fd)  # releases the lock
