"""Sizes a command may ask for: refused before allocating when they cannot fit in memory.

``kinecal simulate irb120 --poses 2000000000`` would need terabytes; numpy would only find
out half-way, with a `MemoryError` (exit 1) or after the machine started swapping. Every
command that allocates in proportion to a count (poses, candidates, stations) first checks
``count * bytes_per_item`` against the memory this process can still get: the kernel's
``MemAvailable`` (Linux), bounded by a cgroup (container) limit when one is set, else the
physical memory. The per-item figures are measured peaks of the commands with a margin
(see each caller); the limit is therefore a property of the machine, not a fixed number.
(This module sits beside `kinecal.errors`, below all layers.)
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from kinecal.errors import InputError

__all__ = ["MAX_JOBS", "available_memory", "check_count", "check_finite"]

#: most jobs one batch run may hold (a study grid expanded): reading and checking a jobs
#: file takes about 1 ms per job, and a billion seeds ran out of memory before any started
MAX_JOBS = 100_000


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        return None
    return int(text) if text.isdigit() else None


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def available_memory() -> int:
    """Bytes of memory a new allocation can still get (best estimate, at least 64 MiB).

    Linux: ``MemAvailable`` of ``/proc/meminfo``, and the room left under a cgroup v2 or
    v1 memory limit when that is smaller. Elsewhere: the available (else total) physical
    pages from ``os.sysconf``; 8 GiB when nothing is known.
    """
    candidates = []
    avail = _meminfo_available()
    if avail is not None:
        candidates.append(avail)
    for limit_file, usage_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        limit = _read_int(limit_file)
        if limit is not None and limit < 1 << 60:
            candidates.append(limit - (_read_int(usage_file) or 0))
    if not candidates:
        for name in ("SC_AVPHYS_PAGES", "SC_PHYS_PAGES"):
            try:
                pages, size = os.sysconf(name), os.sysconf("SC_PAGE_SIZE")
            except (ValueError, OSError, AttributeError):
                continue
            if pages > 0 and size > 0:
                candidates.append(pages * size)
                break
    return max(min(candidates) if candidates else 8 << 30, 64 << 20)


def _gb(n: float) -> str:
    return f"{n / 1e9:.3g} GB"


def check_count(n: int, option: str, *, bytes_per_item: float, what: str = "poses",
                minimum: int = 1, most: int | None = None) -> int:
    """Refuse a count below `minimum`, above `most`, or one whose memory cannot be had.

    Parameters
    ----------
    n : int
        The requested count.
    option : str
        The option or key that gave it (named in the error).
    bytes_per_item : float
        Peak memory per item of the command (measured, with a margin).
    what : str
        What is counted, for the message.
    minimum : int
        Smallest count accepted.
    most : int, optional
        Largest count accepted whatever the memory (work that would take hours even where
        it fits, such as `MAX_JOBS` batch jobs).

    Returns
    -------
    int
        `n`.

    Raises
    ------
    InputError
        ``n < minimum``, ``n > most``, or ``n * bytes_per_item`` above `available_memory`.
    """
    if n < minimum:
        raise InputError(f"expected at least {minimum} {what}, got {n}", option=option)
    if most is not None and n > most:
        raise InputError(f"{n:,} {what}: expected at most {most:,}", option=option)
    need, have = n * float(bytes_per_item), available_memory()
    if need > have:
        most = max(int(have // bytes_per_item), minimum)
        raise InputError(f"{n} {what} need about {_gb(need)} of memory, {_gb(have)} are "
                         f"available: expected at most about {most:,}", option=option)
    return n


def check_finite(value: float | None, option: str, *, minimum: float | None = 0.0,
                 positive: bool = False) -> float | None:
    """Refuse NaN, infinity and values below `minimum` (or not above 0 when `positive`).

    None (an option not given) passes through.
    """
    if value is None:
        return None
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"expected a finite number, got {value}", option=option)
    if positive and v <= 0:
        raise InputError(f"expected a positive number, got {value}", option=option)
    if minimum is not None and v < minimum:
        raise InputError(f"expected a number >= {minimum:g}, got {value}", option=option)
    return v
