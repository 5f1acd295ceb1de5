"""Do a bag's joint and measurement clocks overlap?

Rows pair each measurement with the joints by ``header.stamp``. A publisher whose clock is
another's (a tracker PC stamping in its own epoch, a simulated clock, a stamp left in
seconds since boot) gives measurements that fall in no dwell: every dwell would be
dropped for "no message", which hides the cause. `StreamTimes` keeps each stream's first
and last stamp as the bag streams by; `check_overlap` names both clocks' ranges when a
stream has messages but none overlapping the joints' time.
"""

from __future__ import annotations

from datetime import UTC, datetime

from kinecal.errors import InputError

__all__ = ["StreamTimes", "check_overlap"]


def _when(ns: float) -> str:
    """A time (ns since the epoch) as UTC ISO 8601, or the raw seconds when out of range."""
    try:
        return datetime.fromtimestamp(ns * 1e-9, UTC).isoformat(timespec="milliseconds")
    except (OverflowError, OSError, ValueError):
        return f"{ns * 1e-9:.6g} s"


class StreamTimes:
    """First and last stamp (s on the joints' clock, from `t0`) and count, per stream."""

    def __init__(self) -> None:
        self.ranges: dict[str, list[float]] = {}

    def add(self, topic: str, t: float) -> None:
        r = self.ranges.get(topic)
        if r is None:
            self.ranges[topic] = [t, t, 1]
        else:
            r[0], r[1], r[2] = min(r[0], t), max(r[1], t), r[2] + 1


def check_overlap(times: StreamTimes, joints: str, span: tuple[float, float], t0: int,
                  used: dict[str, int], option: str = "--joints") -> None:
    """`InputError` naming both ranges when a stream's messages all lie outside the joint
    samples' time `span` (s from `t0` ns) and none fell in a dwell (`used`: messages per
    topic that did)."""
    for topic, (first, last, n) in times.ranges.items():
        if used.get(topic, 0) or (last >= span[0] and first <= span[1]):
            continue
        raise InputError(
            f"{topic}: its {n} messages are stamped {_when(t0 + first * 1e9)} to "
            f"{_when(t0 + last * 1e9)} (UTC), the joints of {joints} "
            f"{_when(t0 + span[0] * 1e9)} to {_when(t0 + span[1] * 1e9)}: the two clocks do "
            "not overlap, so no measurement falls in a dwell (rows pair them by "
            "header.stamp: stamp both with one clock)", option=option)
