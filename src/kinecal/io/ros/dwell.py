"""Where a robot dwells: its joints still for at least a stated time.

A joint sample at time ``t_k`` is *still* when every joint moved less than ``tol * h``
since the latest sample at or before ``t_k - h`` (``h`` the speed window, default
``min(0.1 s, dwell / 2)``): its speed over that window is below ``tol``. A speed over a
window rather than between neighbouring samples is blind to the encoders' quantization
at high rates and ends a stop's window only once the robot has settled for ``h``. A
*dwell* is a maximal run of still samples spanning at least the dwell time; a shorter run
(at least 3 samples) is a *short stop*, reported but not kept.

The joint stream is fed in chunks (`DwellFinder.feed`): memory holds one chunk, the last
``h`` seconds before it, and the open run's sums, whatever the length of the recording.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Dwell", "DwellFinder"]

Array = NDArray[np.float64]


@dataclass
class Dwell:
    """A still run of joint samples.

    Attributes
    ----------
    start, end : float
        Times of its first and last sample (s, on the caller's clock).
    q : ndarray, shape (n_joints,)
        Mean joint values over its samples.
    samples : int
    """

    start: float
    end: float
    q: Array
    samples: int

    @property
    def duration(self) -> float:
        return self.end - self.start


class DwellFinder:
    """Find dwells in a joint stream fed chunk by chunk (module docstring).

    Parameters
    ----------
    n_joints : int
    dwell : float
        Minimum duration (s) of a dwell.
    tol : float
        Speed tolerance (joint units per second: rad/s, or length unit/s for prismatic).
    window : float, optional
        Speed window ``h`` (s); default ``min(0.1, dwell / 2)``.
    """

    def __init__(self, n_joints: int, dwell: float, tol: float,
                 window: float | None = None) -> None:
        self.n = n_joints
        self.dwell, self.tol = float(dwell), float(tol)
        self.window = float(min(0.1, dwell / 2) if window is None else window)
        self._t = np.empty(0)
        self._q = np.empty((0, n_joints))
        self._run: list | None = None  # [start, end, sum q, count]
        self.dwells: list[Dwell] = []
        self.short: list[Dwell] = []
        self.samples = 0
        self.skipped = 0  # samples whose time did not increase

    def _close(self) -> None:
        start, end, total, count = self._run
        self._run = None
        d = Dwell(start, end, total / count, count)
        if d.duration >= self.dwell:
            self.dwells.append(d)
        elif count >= 3:
            self.short.append(d)

    def _increasing(self, t: Array, q: Array) -> tuple[Array, Array]:
        last = self._t[-1] if self._t.size else -np.inf
        keep = t > np.maximum.accumulate(np.r_[last, t])[:-1]
        self.skipped += int((~keep).sum())
        return t[keep], q[keep]

    def feed(self, t: Array, q: Array) -> None:
        """Add samples: times ``(m,)`` (s, increasing; others are skipped) and joints
        ``(m, n_joints)``."""
        t, q = self._increasing(np.asarray(t, dtype=float), np.asarray(q, dtype=float))
        if not t.size:
            return
        self.samples += t.size
        T, Q = np.r_[self._t, t], np.vstack([self._q, q])
        j = np.searchsorted(T, t - self.window, side="right") - 1
        ok = j >= 0
        jj = np.where(ok, j, 0)
        speed = np.abs(q - Q[jj]).max(axis=1) / np.maximum(t - T[jj], 1e-300)
        still = ok & (speed <= self.tol)
        edges = np.flatnonzero(np.diff(np.r_[0, still.astype(np.int8), 0]))
        if self._run is not None and not still[0]:
            self._close()
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            total = q[a:b].sum(axis=0)
            if a == 0 and self._run is not None:
                self._run[1] = t[b - 1]
                self._run[2] = self._run[2] + total
                self._run[3] += b - a
            else:
                self._run = [t[a], t[b - 1], total, b - a]
            if b < t.size:
                self._close()
        keep = T >= t[-1] - self.window
        first = max(int(np.argmax(keep)) - 1, 0)  # and the sample just before the window
        self._t, self._q = T[first:], Q[first:]

    def finish(self) -> list[Dwell]:
        """Close the open run; the dwells found, in time order."""
        if self._run is not None:
            self._close()
        return self.dwells
