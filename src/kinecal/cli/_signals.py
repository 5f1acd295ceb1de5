"""SIGTERM and SIGHUP unwind a command like Ctrl-C (kept light: no numpy at import)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

__all__ = ["Terminated", "terminate_like_interrupt"]


class Terminated(BaseException):
    """SIGTERM (or SIGHUP) received: unwinds the command like Ctrl-C does, so that every
    ``finally`` runs (temporary files removed, the batch summary written); exit status 143.
    (Not a KeyboardInterrupt: typer would turn that into exit 130.)"""


@contextlib.contextmanager
def terminate_like_interrupt() -> Iterator[None]:
    """SIGTERM and SIGHUP raise `Terminated` in the main thread, once; the previous
    handlers are restored on exit."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    fired = []

    def handler(signum, frame):
        if not fired:  # a second signal must not abort the clean-up of the first
            fired.append(signum)
            raise Terminated(signum)

    sigs = [s for s in ("SIGTERM", "SIGHUP") if hasattr(signal, s)]
    old = {s: signal.signal(getattr(signal, s), handler) for s in sigs}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(getattr(signal, s), h)
