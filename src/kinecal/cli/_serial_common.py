"""Helpers shared by the serial-arm command modules (``fk``, ``simulate``, ``calibrate``).

Reading a calibration result (``fk --params``, ``export``, ``compensate``) is
`kinecal.io.results`. No command is registered here: importing it loads no command module.
"""

from __future__ import annotations

from kinecal.errors import InputError

__all__ = ["POSE_BYTES", "free_option"]

#: peak memory of simulate / identifiability per random pose and per joint (+10): measured
#: 330 B (irb120, 6 joints) and 580 B with orientations, taken with a margin
POSE_BYTES = 64


def free_option(free: str) -> str | list[str]:
    """A ``--free`` value: ``all``, ``identifiable`` or the list of comma-separated names."""
    if free in ("all", "identifiable"):
        return free
    names = [n.strip() for n in free.split(",") if n.strip()]
    if not names:
        raise InputError("expected all, identifiable or comma-separated parameter names",
                         option="--free")
    return names
