"""Residual blocks from in-memory measurements: one block per data set, by its kind."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from kinecal.calibration.blocks.ballbar import BallbarBlock
from kinecal.calibration.blocks.base import ResidualBlock
from kinecal.calibration.blocks.carried import CarriedPointBlock
from kinecal.calibration.blocks.pair import PairBlock
from kinecal.calibration.blocks.plane import PlaneBlock
from kinecal.calibration.blocks.point import PointBlock
from kinecal.calibration.blocks.stations import StationBlock
from kinecal.calibration.blocks.tracker import TrackerBlock
from kinecal.calibration.diagnostics.noise import check_stated_sigma
from kinecal.data import GaugeMeasurements, Measurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.markers import remap_markers
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["BLOCK_TYPES", "DataSet", "kind_of", "make_blocks", "marker_names"]

#: the block of each gauge kind (`kinecal.data.GAUGE_KINDS`)
BLOCK_TYPES = {"ballbar": BallbarBlock, "pair": PairBlock, "point": PointBlock,
               "plane": PlaneBlock}

DataSet = Measurements | GaugeMeasurements | ResidualBlock


def kind_of(data: DataSet) -> str:
    """``tracker``, ``ballbar``, ``pair``, ``point``, ``plane`` (or a block's kind)."""
    if isinstance(data, Measurements):
        return "tracker"
    return data.kind


def marker_names(data: Sequence[DataSet]) -> list[str]:
    """Every marker name the data sets use, in order of first appearance."""
    names: list[str] = []
    for d in data:
        for n in getattr(d, "marker_names", ()) or ():
            if n not in names:
                names.append(n)
    return names


def _remapped(data, model: SerialModel):
    """`data` with its marker indices into `model`'s markers (by name)."""
    if data.marker is None or tuple(data.marker_names) == model.marker_names:
        return data
    m = remap_markers(data.marker, data.marker_names, model.marker_names)
    return dataclasses.replace(data, marker=m, marker_names=model.marker_names)


def make_blocks(model: SerialModel, data: Sequence[DataSet],
                sigma: Sequence[float | None] | None = None,
                rotation_weight: float | None = None) -> list[ResidualBlock]:
    """One residual block per data set (blocks given as such pass through).

    Parameters
    ----------
    model : SerialModel
        The model (with the markers the data name).
    data : sequence
        `Measurements` (tracker points / poses), `GaugeMeasurements` (a gauge kind) or
        ready `ResidualBlock` objects (another kind, e.g. a camera's).
    sigma : sequence of float or None, optional
        Stated noise per data set (overrides a file's ``sigma`` column); None: the file's
        column, else estimated.
    rotation_weight : float, optional
        Tracker poses: length units per rad of the rotation rows.
    """
    sigma = [None] * len(data) if sigma is None else list(sigma)
    if len(sigma) != len(data):
        raise InputError(f"sigma: expected one value (or None) per data set, {len(data)}, "
                         f"got {len(sigma)}", option="--sigma")
    blocks: list[ResidualBlock] = []
    for d, s in zip(data, sigma, strict=True):
        if isinstance(d, ResidualBlock):
            if s is not None:
                d.sigma, d.obs_sigma = float(s), None
            blocks.append(d)
        elif isinstance(d, Measurements) and d.station is not None:
            blocks.append(StationBlock(_remapped(d, model), s, rotation_weight))
        elif isinstance(d, Measurements):
            blocks.append(TrackerBlock(_remapped(d, model), s, rotation_weight))
        elif isinstance(d, GaugeMeasurements) and d.carrier is not None and (
                np.asarray(d.carrier) >= 0).any():  # points on a moving link of a system
            blocks.append(CarriedPointBlock(_remapped(d, model), s))
        elif isinstance(d, GaugeMeasurements):
            blocks.append(BLOCK_TYPES[d.kind](_remapped(d, model), s))
        else:
            raise InputError(f"data: expected Measurements, GaugeMeasurements or a residual "
                             f"block, got {type(d).__name__}")
        b = blocks[-1]
        check_stated_sigma(model, s)
        if b.obs_sigma is not None and np.size(b.obs_sigma):
            try:
                check_stated_sigma(model, float(np.min(b.obs_sigma)))
            except InputError as exc:
                raise InputError(f"column sigma: {exc.message}", file=b.source) from None
        if len(blocks[-1].q) and np.shape(blocks[-1].q)[1] != model.n_joints:
            raise InputError(f"{blocks[-1].name}: {np.shape(blocks[-1].q)[1]} joint values "
                             f"per row, model {model.name!r} has {model.n_joints} joints")
    _check_station_names(blocks)
    return blocks


def _check_station_names(blocks: Sequence[ResidualBlock]) -> None:
    """Each station in one set only: two sets naming one station would be fitted as two
    frames under one name."""
    seen: dict[str, str] = {}
    for b in blocks:
        for name in getattr(b, "names", ()) if isinstance(b, StationBlock) else ():
            if name in seen:
                raise InputError(f"station {name} appears in {seen[name]} and {b.name}: put "
                                 "the rows of one set-up in one file, or name the stations "
                                 "apart")
            seen[name] = b.name
