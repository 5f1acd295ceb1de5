"""Where a robot dwells: its joints still for at least a stated time.

A joint sample at time ``t_k`` is *still* when its speed is below ``tol`` over the speed
window ``h`` (default ``min(0.1 s, dwell / 2)``) on both sides: every joint moved less than
``tol`` times the time to the latest sample at or before ``t_k - h`` and to the first one
at or after ``t_k + h`` (one side only at the ends of the recording). A speed over a
window rather than between neighbouring samples is blind to the encoders' quantization at
high rates; looking both ways keeps the last samples of a deceleration and the first of
an acceleration, whose neighbours barely differ, out of the dwell. A *dwell* is a maximal
run of still samples spanning at least the dwell time; a shorter run (at least 3 samples)
is a *short stop*, reported but not kept.

The joint stream is fed in chunks (`DwellFinder.feed`); a sample is judged once the
samples ``h`` after it have come. Memory holds one chunk, ``h`` seconds on each side and
the open run's sums, whatever the length of the recording.
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
        Times of its first and last still sample (s, on the caller's clock): the window
        averaged.
    span : float
        How long the joints were still: ``end - start`` plus the speed window on each side.
    q : ndarray, shape (n_joints,)
        Mean joint values over its samples.
    samples : int
    """

    start: float
    end: float
    q: Array
    samples: int
    span: float = 0.0


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
        self._pending = 0  # index in the buffer of the first sample not yet judged
        self._run: list | None = None  # [start, end, sum q, count]
        self.dwells: list[Dwell] = []
        self.short: list[Dwell] = []
        self.samples = 0
        self.skipped = 0  # samples whose time did not increase
        self.t_last = 0.0  # time of the last sample fed (s)

    def _close(self) -> None:
        start, end, total, count = self._run
        self._run = None
        d = Dwell(start, end, total / count, count, end - start + 2 * self.window)
        if d.span >= self.dwell:
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
        self.t_last = float(t[-1])
        self.samples += t.size
        self._t, self._q = np.r_[self._t, t], np.vstack([self._q, q])
        self._judge(final=False)

    def _speeds(self, k: slice) -> NDArray[np.bool_]:
        """Still mask of samples `k` of the buffer (module docstring)."""
        T, Q, h = self._t, self._q, self.window
        t, q = T[k], Q[k]
        jb = np.searchsorted(T, t - h, side="right") - 1
        jf = np.searchsorted(T, t + h, side="left")
        back, fwd = jb >= 0, jf < T.size
        jb, jf = np.where(back, jb, 0), np.where(fwd, jf, T.size - 1)
        vb = np.abs(q - Q[jb]).max(axis=1) / np.maximum(t - T[jb], 1e-300)
        vf = np.abs(Q[jf] - q).max(axis=1) / np.maximum(T[jf] - t, 1e-300)
        return ((back | fwd) & np.where(back, vb <= self.tol, True)
                & np.where(fwd, vf <= self.tol, True))

    def _judge(self, final: bool) -> None:
        """Judge the pending samples whose forward window is complete (all when `final`)."""
        T, p = self._t, self._pending
        n = T.size - p if final else int(np.searchsorted(T[p:], T[-1] - self.window,
                                                         side="right"))
        if n <= 0:
            return
        k = slice(p, p + n)
        self._runs(T[k], self._q[k], self._speeds(k))
        p += n
        if p < T.size:  # keep h seconds before the next pending sample
            first = max(int(np.searchsorted(T, T[p] - self.window, side="right")) - 1, 0)
        else:
            first = max(int(np.searchsorted(T, T[-1] - self.window, side="right")) - 1, 0)
        self._t, self._q, self._pending = T[first:], self._q[first:], p - first

    def _runs(self, t: Array, q: Array, still: NDArray[np.bool_]) -> None:
        """Extend, open and close runs over judged samples in time order."""
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

    def finish(self) -> list[Dwell]:
        """Close the open run; the dwells found, in time order."""
        if self._t.size:
            self._judge(final=True)
        if self._run is not None:
            self._close()
        return self.dwells
