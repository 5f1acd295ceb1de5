"""Several tracker files as one: the fast path of `calibrate` for tracker-only data sets.

Tracker files calibrated together share one measurement frame (the model's base frame: one
tracker station). They are one pose set for the chunked solver when their noise is known
relative to each other: all stated (``sigma`` per file: rows weighted by ``(s_0 / s_i)^2``
and the stated noise ``s_0`` the smallest) or none stated (the same instrument: equal
weights). Anything else (a gauge kind among them, some noises stated and others not,
orientations in some files only, other markers) is a stacked problem
(`kinecal.calibration.blocks`), which estimates each file's noise.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinecal.data import Measurements
from kinecal.errors import InputError

__all__ = ["data_sets", "merge_tracker_sets", "tracker_input"]


def merge_tracker_sets(sets: Sequence[object], sigma: Sequence[float | None]
                       ) -> tuple[Measurements, float | None] | None:
    """One `Measurements` and its stated noise for tracker-only `sets`, or None.

    Parameters
    ----------
    sets : sequence
        Data sets of any kinds.
    sigma : sequence of float or None
        Stated noise per set (length unit), aligned with `sets`.
    """
    if not sets or not all(type(s) is Measurements for s in sets):
        return None
    if any(s.station is not None for s in sets):
        return None  # several set-ups: a stacked problem (calibration.blocks.stations)
    if len(sets) == 1:
        return sets[0], sigma[0]
    if any(s.sigma is not None for s in sets):
        return None  # rows weighted per axis, each file its own floor: a stacked problem
    known = [s is not None for s in sigma]
    if any(known) and not all(known):
        return None
    if len({s.rotations is None for s in sets}) > 1 or len({s.marker_names for s in sets}) > 1:
        return None
    if len({np.shape(s.q)[1] for s in sets}) > 1:
        return None
    ref = min(sigma) if all(known) else None
    weights = None
    if ref is not None or any(s.weights is not None for s in sets):
        weights = np.concatenate([
            (np.ones(len(s)) if s.weights is None else np.asarray(s.weights, float))
            * (1.0 if ref is None else (ref / sig) ** 2) for s, sig in zip(sets, sigma,
                                                                          strict=True)])
    rotations = (None if sets[0].rotations is None
                 else np.concatenate([s.rotations for s in sets]))
    marker = None if sets[0].marker is None else np.concatenate([s.marker for s in sets])
    # the conditions of the rows (temperature, time) when every set has them
    conditions = {k: np.concatenate([getattr(s, k) for s in sets])
                  if all(getattr(s, k) is not None for s in sets) else None
                  for k in ("temperature", "time")}
    merged = Measurements(np.concatenate([s.q for s in sets]),
                          np.concatenate([s.xyz for s in sets]), weights,
                          " + ".join(s.source for s in sets), rotations, marker,
                          sets[0].marker_names, **conditions)
    return merged, ref


def data_sets(data: object, sigma: object, what: str) -> tuple[list, list]:
    """Data sets and their stated noise, aligned (a float noise applies to every set)."""
    sets = [data] if isinstance(data, Measurements) or hasattr(data, "kind") else list(data)
    if sigma is None or np.isscalar(sigma):
        return sets, [sigma] * len(sets)
    sigma = list(sigma)
    if len(sigma) != len(sets):
        raise InputError(f"sigma: expected one value (or None) per {what} set ({len(sets)}), "
                         f"got {len(sigma)}", option="--sigma")
    return sets, sigma


def tracker_input(model, data, free, rank_tol: float, rotation_weight):
    """`data` as the calibration takes it: rows from several stations as a list (one
    stacked problem, `kinecal.calibration.blocks.stations`); rows with per-axis standard
    deviations with their floor estimated (`kinecal.calibration.serial.sigma_floor`)."""
    if isinstance(data, Measurements) and data.station is not None:
        return [data]
    if isinstance(data, Measurements) and data.sigma is not None:
        from kinecal.calibration.serial.sigma_floor import with_sigma_floor

        return with_sigma_floor(model, data, free, rank_tol=rank_tol,
                                rotation_weight=rotation_weight)
    return data

