"""Executors for batch runs: a local process pool, or a Dask ``distributed`` cluster.

Both are plain `concurrent.futures.Executor` objects, so `kinecal.batch.run_batch` runs
on either (and on any other executor, e.g. a thread pool).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
from collections.abc import Iterator
from concurrent.futures import Executor, ProcessPoolExecutor

from kinecal import _blas
from kinecal._temps import pid_alive
from kinecal.errors import InputError

__all__ = ["BLAS_THREAD_VARS", "TRACKER_FILTER", "dask_executor", "local_executor",
           "quiet_resource_tracker", "single_thread_blas"]

#: kinecal's matrices are small: one BLAS thread per worker process is 10-50x faster than
#: several threads competing for the same cores (`kinecal._blas`)
BLAS_THREAD_VARS = _blas.BLAS_THREAD_VARS

#: how long to try to reach a Dask scheduler before giving up
CONNECT_TIMEOUT = "10s"


def single_thread_blas() -> None:
    """Ask worker processes started from now on for single-threaded BLAS.

    Sets the variables in this process's environment (inherited by the workers); an
    explicit user setting wins.
    """
    for var in BLAS_THREAD_VARS:
        os.environ.setdefault(var, "1")


#: the warning filter that `quiet_resource_tracker` passes to multiprocessing's helpers
TRACKER_FILTER = "ignore:resource_tracker:UserWarning"


def quiet_resource_tracker() -> None:
    """Keep multiprocessing's resource tracker quiet when this process is killed.

    The tracker (a helper process started with the pool) removes the pool's semaphores
    when the coordinator dies without doing so itself (SIGKILL), which is its job, and
    warns "There appear to be N leaked semaphore objects" on the terminal the coordinator
    left. Helper processes are started with this interpreter's ``-W`` options
    (``sys.warnoptions``), so the filter added here reaches the tracker (and the fork
    server) started from now on; this process's own warning filters are unchanged.
    """
    if TRACKER_FILTER not in sys.warnoptions:
        sys.warnoptions.append(TRACKER_FILTER)


def local_executor(workers: int | None = None) -> ProcessPoolExecutor:
    """A process pool of `workers` processes (default: the number of CPUs).

    Workers are forked from a fork server that has already imported the calibration
    code, so a pool (or its replacement after a worker died) starts in milliseconds and
    no thread of the parent (e.g. a Dask client) is copied into the workers.

    Every worker ends itself when the process that created the pool dies, however it
    died (SIGKILL included): it is never left behind as an orphan computing a job nobody
    will collect (`watch_parent`).
    """
    if workers is not None and workers < 1:
        raise InputError(f"expected a positive number of workers, got {workers}",
                         option="--workers")
    single_thread_blas()
    quiet_resource_tracker()
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["kinecal.batch.work", "kinecal.calibration.serial.api"])
    return ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1, mp_context=ctx,
                               initializer=watch_parent, initargs=(os.getpid(),))


#: how often a worker checks that its coordinator is alive (seconds)
WATCH_INTERVAL = 0.5


def watch_parent(pid: int, interval: float = WATCH_INTERVAL) -> None:
    """Make this worker process end when the coordinating process `pid` dies.

    A pool worker is a child of the fork server, not of the coordinator, and a
    coordinator killed by SIGKILL runs no clean-up: without this, its workers would finish
    (or hang on) their jobs as orphans. On Linux the kernel delivers SIGKILL to the
    worker when its parent (the fork server, which exits with the coordinator) dies
    (``PR_SET_PDEATHSIG``); on every system a daemon thread also checks every `interval`
    seconds that `pid` is alive and ends the worker at once (``os._exit``) when not.
    """
    import signal
    import sys
    import threading
    import time

    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):
            pass
    if os.name == "nt":  # os.kill(pid, 0) would not be a probe there
        return

    def watch() -> None:
        while pid_alive(pid):
            time.sleep(interval)
        os._exit(1)

    threading.Thread(target=watch, name="kinecal-watch-parent", daemon=True).start()


@contextlib.contextmanager
def dask_executor(address: str | None = None, workers: int | None = None) -> Iterator[Executor]:
    """A Dask executor: connect to the scheduler at `address`, or start a local cluster.

    Parameters
    ----------
    address : str, optional
        Scheduler address (``tcp://host:8786``). Without it a `LocalCluster` of `workers`
        single-threaded worker processes is started on the loopback interface.
    workers : int, optional
        Number of local worker processes (default: the number of CPUs); ignored with an
        address.

    Yields
    ------
    concurrent.futures.Executor
        ``client.get_executor(pure=False)``: a resubmitted job is a new task, not the
        erred one.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise InputError("the Dask executor needs the optional extra: pip install "
                         "'kinecal[dask]'", option="--executor") from None
    if workers is not None and workers < 1:
        raise InputError(f"expected a positive number of workers, got {workers}",
                         option="--workers")
    single_thread_blas()
    with contextlib.ExitStack() as stack:
        if address is None:
            cluster = stack.enter_context(LocalCluster(
                n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0"))
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(address, timeout=CONNECT_TIMEOUT))
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(f"cannot connect to the Dask scheduler {address!r} ({exc})",
                                 option="--scheduler") from None
        executor = client.get_executor(pure=False)
        try:
            yield executor
        finally:
            executor.shutdown(wait=False)
