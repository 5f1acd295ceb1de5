"""Calibration data of the parallel-link CMM: measured probe poses and leg readings.

`StewartData` holds what a calibration needs (e.g. probe poses from a laser tracker or a
calibrated artefact, and the machine's leg readings at those poses); `simulate_stewart`
makes such data for a known "true" machine (`perturb_geometry`), with measurement noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kinecal.errors import InputError
from kinecal.kinematics.stewart.forward import expmap
from kinecal.kinematics.stewart.platform import N_PARAMETERS, StewartPlatform
from kinecal.spatial import matrix_from_rpy, rpy_from_matrix

__all__ = ["ARCSEC", "StewartData", "perturb_geometry", "simulate_stewart"]

Array = NDArray[np.float64]

#: one arc second in rad
ARCSEC = np.pi / (180.0 * 3600.0)


@dataclass
class StewartData:
    """Calibration data: measured probe poses and leg readings.

    Attributes
    ----------
    poses : ndarray, shape (N, 6)
        Measured probe poses (length unit, rad).
    legs : ndarray, shape (N, 6)
        Leg readings (length unit).
    true_poses : ndarray, shape (N, 6), optional
        Noise-free poses (simulation only).
    true_legs : ndarray, shape (N, 6), optional
        Noise-free readings (simulation only).
    """

    poses: Array
    legs: Array
    true_poses: Array | None = None
    true_legs: Array | None = None

    def __post_init__(self) -> None:
        self.poses = np.asarray(self.poses, dtype=float)
        self.legs = np.asarray(self.legs, dtype=float)
        if self.poses.ndim != 2 or self.poses.shape[1] != 6 or self.legs.shape != self.poses.shape:
            raise InputError(
                f"poses and legs must both be (N, 6), got {self.poses.shape}, {self.legs.shape}"
            )
        bad = ~(np.isfinite(self.poses).all(1) & np.isfinite(self.legs).all(1))
        if bad.any():
            raise InputError("poses and legs must be finite", row=int(np.argmax(bad)) + 1)

    def __len__(self) -> int:
        return int(self.poses.shape[0])


def perturb_geometry(
    geom: StewartPlatform, amplitude: float, rng: np.random.Generator | int | None = None
) -> StewartPlatform:
    """A "true" machine: every one of the 42 parameters off by ``U(-amplitude, amplitude)``."""
    gen = np.random.default_rng(rng)
    return geom.with_parameters(geom.parameters + gen.uniform(-amplitude, amplitude, N_PARAMETERS))


def _noisy_poses(poses: Array, pos_sigma: float, rot_sigma: float, gen) -> Array:
    R = matrix_from_rpy(poses[:, 3:])
    Rn = expmap(gen.normal(0.0, rot_sigma, (len(poses), 3))) @ R
    t = poses[:, :3] + gen.normal(0.0, pos_sigma, (len(poses), 3))
    return np.concatenate([t, rpy_from_matrix(Rn)], axis=1)


def simulate_stewart(
    true_geom: StewartPlatform,
    n_poses: int,
    *,
    rng: np.random.Generator | int | None = None,
    position_noise: float = 1e-6,
    rotation_noise: float = ARCSEC,
    leg_noise: float = 1e-6,
    box: ArrayLike | None = None,
) -> StewartData:
    """Simulated calibration data of a machine with geometry `true_geom`.

    Parameters
    ----------
    true_geom : StewartPlatform
        The real machine.
    n_poses : int
        Number of poses (random in the workspace, `StewartPlatform.random_poses`).
    rng : Generator or int, optional
        Random generator or seed.
    position_noise : float
        Std of the measured tip position, per axis (length unit; default 1 um).
    rotation_noise : float
        Std of the measured orientation, per axis of a small rotation (rad; 1 arcsec).
    leg_noise : float
        Std of the leg readings (length unit; default 1 um).
    box : array_like, shape (6, 2), optional
        Pose box (default `StewartPlatform.workspace_box`).

    Returns
    -------
    StewartData
        Measured (noisy) poses and readings, and the noise-free ones.
    """
    gen = np.random.default_rng(rng)
    poses = true_geom.random_poses(n_poses, gen, box)
    legs = true_geom.inverse(poses)
    meas = _noisy_poses(poses, position_noise, rotation_noise, gen)
    readings = legs + gen.normal(0.0, leg_noise, legs.shape)
    return StewartData(meas, readings, poses, legs)

