"""Per-dwell averages of a measurement stream and the tf tree of a bag.

`StreamAverage` sums a stream's vectors (points, or poses whose quaternions are aligned
in sign before summing) per dwell and tracks how much of the dwell the stream covered and
whether the measured position itself stood still (`StreamAverage.motion`: joints that
froze in the recording, or a ``--still`` too loose, make a "dwell" of a moving arm);
`TfTree` does the same per tf edge (``/tf``) and keeps the static edges (``/tf_static``),
then composes, per dwell, the edges on the path between two frames. Inside a dwell every
edge is still, so composing the edges' averages is the lookup at any time of the dwell.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.spatial import invert_transform, transform_from_pq

__all__ = ["MOTION_FLOOR", "MOTION_SIGMAS", "StreamAverage", "TfTree"]

Array = NDArray[np.float64]
#: a stream whose position moves by more than this during a dwell (m) and beyond its own
#: noise (`MOTION_SIGMAS`) is no still measurement
MOTION_FLOOR = 5e-4
MOTION_SIGMAS = 6.0


class StreamAverage:
    """Sums of one stream's values per dwell (`dim` 3: points; 7: x, y, z, qw, qx, qy, qz)."""

    def __init__(self, starts: Array, ends: Array, dim: int) -> None:
        n = len(starts)
        self.starts, self.ends = starts, ends
        self.sums = np.zeros((n, dim))
        self.counts = np.zeros(n, dtype=np.int64)
        self.first = np.full(n, np.nan)
        self.last = np.full(n, np.nan)
        self.gap = np.zeros(n)  # longest silence between two messages inside the dwell
        self._ref = np.zeros((n, 4))
        # the position's mean over the first and the last third of each dwell, and the sum
        # of squared steps between messages (its noise): `motion`
        third = (ends - starts) / 3.0
        self._early_end, self._late_start = starts + third, ends - third
        self.early = np.zeros((n, 3))
        self.late = np.zeros((n, 3))
        self.n_early = np.zeros(n, dtype=np.int64)
        self.n_late = np.zeros(n, dtype=np.int64)
        self.steps = np.zeros(n)
        self._prev = np.zeros((n, 3))

    def add(self, k: int, t: float, v: Array) -> None:
        """Add value `v` measured at time `t` inside dwell `k`."""
        xyz = v[:3]
        if self.counts[k]:
            self.gap[k] = max(self.gap[k], t - self.last[k])
            self.steps[k] += float(np.sum((xyz - self._prev[k]) ** 2))
        else:
            self.first[k] = t
            self._ref[k] = v[3:7] if v.size == 7 else 0.0
        self.last[k] = t
        self._prev[k] = xyz
        if t <= self._early_end[k]:
            self.early[k] += xyz
            self.n_early[k] += 1
        if t >= self._late_start[k]:
            self.late[k] += xyz
            self.n_late[k] += 1
        if v.size == 7 and float(v[3:7] @ self._ref[k]) < 0.0:
            v = np.r_[v[:3], -v[3:7]]  # q and -q are the same rotation
        self.sums[k] += v
        self.counts[k] += 1

    def mean(self, k: int) -> Array:
        """The average over dwell `k` (quaternion part normalised)."""
        m = self.sums[k] / self.counts[k]
        if m.size == 7:
            m[3:] /= np.linalg.norm(m[3:])
        return m

    def motion(self, k: int) -> tuple[float, float]:
        """How far the position moved during dwell `k` (m: the distance between its means
        over the first and the last third) and the standard deviation of that distance
        from the stream's own noise (m, from the steps between messages)."""
        n = int(self.counts[k])
        if n < 3 or not (self.n_early[k] and self.n_late[k]):
            return 0.0, 0.0
        drift = float(np.linalg.norm(self.late[k] / self.n_late[k]
                                     - self.early[k] / self.n_early[k]))
        noise2 = self.steps[k] / (2.0 * (n - 1))  # E|noise|^2 of white noise
        return drift, float(np.sqrt(noise2 * (1.0 / self.n_early[k] + 1.0 / self.n_late[k])))

    def moving(self, k: int) -> float | None:
        """The drift (m) of dwell `k` when the position moved (beyond `MOTION_FLOOR` and
        `MOTION_SIGMAS` of its noise), else None."""
        drift, sigma = self.motion(k)
        return drift if drift > max(MOTION_FLOOR, MOTION_SIGMAS * sigma) else None

    def problem(self, k: int, what: str) -> str | None:
        """Why dwell `k` cannot use this stream (None when it can): no message at all,
        (3 messages or more) silent over more than half of the dwell, or moving while
        the joints were still (`moving`)."""
        if not self.counts[k]:
            return f"no {what} message during the dwell"
        if self.counts[k] < 3:
            return None
        drift = self.moving(k)
        if drift is not None:
            return (f"moving: {what} moved {drift * 1000:.4g} mm during the dwell while the "
                    "joints read still (joint_states frozen, or --still too loose)")
        span = self.ends[k] - self.starts[k]
        silent = max(self.first[k] - self.starts[k], self.ends[k] - self.last[k], self.gap[k])
        if silent > 0.5 * span:
            return (f"partial: {what} silent for {silent:.2f} s of the {span:.2f} s dwell "
                    f"(messages from +{self.first[k] - self.starts[k]:.2f} s to "
                    f"+{self.last[k] - self.starts[k]:.2f} s)")
        return None


class TfTree:
    """tf edges averaged per dwell, static edges kept, and lookups along the tree."""

    def __init__(self, starts: Array, ends: Array) -> None:
        self.starts, self.ends = starts, ends
        self.dynamic: dict[tuple[str, str], StreamAverage] = {}
        self.static: dict[tuple[str, str], Array] = {}

    def add(self, parent: str, child: str, k: int | None, t: float, pq: Array,
            static: bool) -> None:
        """One transform of `child` in `parent`: static, or inside dwell `k` (None: outside
        every dwell, only the edge's existence is recorded)."""
        edge = (parent, child)
        if static:
            self.static[edge] = pq
            return
        acc = self.dynamic.get(edge)
        if acc is None:
            acc = self.dynamic[edge] = StreamAverage(self.starts, self.ends, 7)
        if k is not None:
            acc.add(k, t, pq)

    def path(self, parent: str, child: str) -> list[tuple[tuple[str, str], bool]]:
        """The edges from `parent` to `child` (each with True when walked parent to child);
        `InputError` when a frame is unknown or the two are not connected."""
        links: dict[str, list] = {}
        for a, b in list(self.dynamic) + list(self.static):
            links.setdefault(a, []).append((b, (a, b), True))
            links.setdefault(b, []).append((a, (a, b), False))
        for frame in (parent, child):
            if frame not in links:
                raise InputError(f"frame {frame!r} is not in /tf or /tf_static (frames: "
                                 f"{', '.join(sorted(links)) or 'none'})", option="--tf")
        prev: dict[str, tuple] = {parent: ()}
        todo = deque([parent])
        while todo:
            a = todo.popleft()
            for b, edge, forward in links[a]:
                if b not in prev:
                    prev[b] = (a, edge, forward)
                    todo.append(b)
        if child not in prev:
            raise InputError(f"frames {parent!r} and {child!r} are not connected in the tf "
                             "tree", option="--tf")
        out, node = [], child
        while node != parent:
            a, edge, forward = prev[node]
            out.append((edge, forward))
            node = a
        return out[::-1]

    def lookup(self, path: list, k: int) -> tuple[Array | None, str | None]:
        """The transform along `path` in dwell `k` ``(4, 4)``, or None and the reason."""
        T = np.eye(4)
        for (a, b), forward in path:
            if (a, b) in self.static:
                E = transform_from_pq(self.static[(a, b)])
            else:
                acc = self.dynamic[(a, b)]
                why = acc.problem(k, f"tf {a}->{b}")
                if why is not None:
                    return None, why
                E = transform_from_pq(acc.mean(k))
            T = T @ (E if forward else invert_transform(E))
        return T, None
