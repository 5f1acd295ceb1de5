"""BLAS threads of kinecal's small dense products.

kinecal's dense products are tall and thin (``J^T J`` of a few 10^5 rows by tens of
columns, QR factors of chunks, tens-by-tens Cholesky solves). A multi-threaded BLAS gains
nothing on them when the machine is quiet (`calibrate()` on 10^5 UR5 poses: 0.42 s on two
threads, 0.43 s on one) and loses 5-34x when another process keeps the cores busy
(OpenBLAS's threads spin waiting for each other: 1.7 s against 28-53 s at load 9 on two
cores, ``benchmarks/bench_blas.py``). So kinecal's solvers run their products on
`threads()` BLAS threads (one unless ``KINECAL_BLAS_THREADS`` says otherwise; ``0`` leaves
the libraries' own setting), whatever numpy's default.

Two ways, cheapest first:

* the command line sets ``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` /
  ``MKL_NUM_THREADS`` to 1 before numpy loads (`pin_environment`; an explicit user setting
  wins): the libraries start on one thread and nothing more is done (no threadpoolctl
  import, no library scan);
* in a Python session whose libraries started otherwise, `small_products` (a decorator on
  the solvers' entry points) limits the BLAS libraries to `threads()` with threadpoolctl for
  the call and restores them after (about 10 us a call; the loaded libraries are scanned
  again, 1-4 ms, only when a module was imported since the last scan).
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

__all__ = ["BLAS_THREAD_VARS", "pin_environment", "small_products", "threads"]

#: the variables the BLAS libraries read when they load (OpenBLAS, OpenMP builds, MKL)
BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: kinecal's own setting: BLAS threads of its products (``0``: the libraries' own)
THREADS_VAR = "KINECAL_BLAS_THREADS"

F = TypeVar("F", bound=Callable[..., Any])

_state = threading.local()
_lock = threading.Lock()
#: True when every BLAS library of this process loaded with one thread (the environment
#: said so before numpy was imported)
_started_single = False
_controller: Any = None
_modules_at_scan = -1


def threads() -> int:
    """BLAS threads of kinecal's products: ``KINECAL_BLAS_THREADS`` (default 1; 0 = the
    libraries' own setting, left alone)."""
    raw = os.environ.get(THREADS_VAR, "").strip()
    if not raw:
        return 1
    try:
        return max(0, int(raw))
    except ValueError:
        return 1


def _environment_single() -> bool:
    return all(os.environ.get(var) == "1" for var in BLAS_THREAD_VARS)


def pin_environment() -> None:
    """Ask the BLAS libraries loaded from now on for `threads()` threads (the command line,
    before numpy loads; an explicit user setting of the variables wins)."""
    global _started_single
    n = threads()
    if n > 0:
        for var in BLAS_THREAD_VARS:
            os.environ.setdefault(var, str(n))
    _started_single = "numpy" not in sys.modules and _environment_single()


def _limiter(n: int) -> Any:
    """threadpoolctl's limit of the loaded BLAS libraries to `n` threads, applied (the
    controller kept and rescanned only when a module was imported since: new modules may
    have loaded another BLAS, scipy's own OpenBLAS beside numpy's). Call with `_lock`."""
    global _controller, _modules_at_scan
    if _controller is None or len(sys.modules) != _modules_at_scan:
        # scipy's own OpenBLAS (the solvers' Cholesky and QR) loaded before the scan, not
        # inside the limit where it would keep its threads for the call
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        _modules_at_scan = len(sys.modules)
        _controller = ThreadpoolController()
    return _controller.limit(limits=n, user_api="blas")


#: solver calls inside the limit now (all threads) and the limit they share: the first
#: applies it, the last restores the libraries' setting (the limit is process-wide)
_active = 0
_limit: Any = None


@contextlib.contextmanager
def blas_threads() -> Iterator[None]:
    """Run the block with `threads()` BLAS threads (nested blocks: the outer one decides;
    concurrent blocks in several threads share one limit)."""
    global _active, _limit
    n = threads()
    if getattr(_state, "depth", 0) or n == 0 or (n == 1 and _started_single):
        yield
        return
    _state.depth = 1
    with _lock:
        if _active == 0:
            _limit = _limiter(n)
        _active += 1
    try:
        yield
    finally:
        with _lock:
            _active -= 1
            if _active == 0:
                _limit.restore_original_limits()
                _limit = None
        _state.depth = 0


def small_products(fn: F) -> F:
    """Decorator: `fn` runs its dense products on `threads()` BLAS threads."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with blas_threads():
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


# the environment this process started with: a shell's OPENBLAS_NUM_THREADS=1 etc. before
# numpy was imported makes the limits unnecessary
_started_single = "numpy" not in sys.modules and _environment_single()
