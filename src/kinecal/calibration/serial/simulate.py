"""Synthetic serial-arm measurements: a true geometry, random poses, Gaussian noise.

A *truth file* (JSON) names the true parameter errors in the model file's units::

    {"model": "irb120", "length_unit": "mm", "angle_unit": "deg",
     "errors": {"d1": 0.12, "theta2": -0.03, ...}, "parameters": {...}}

``errors`` is what `read_truth` uses (the deviations from nominal); ``parameters`` (the
true values) is written for the reader's convenience.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import read_json, write_text_atomic
from kinecal.calibration.serial.inputs import as_model
from kinecal.data import Measurements
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import matrix_from_axis_angle

__all__ = [
    "Simulation",
    "random_configurations",
    "random_errors",
    "read_truth",
    "simulate",
    "write_truth",
]

Array = NDArray[np.float64]


@dataclass(frozen=True, repr=False)
class Simulation:
    """Synthetic data with its truth.

    Attributes
    ----------
    data : Measurements
        Noisy measurements.
    true_params : ndarray, shape (n_params,)
        True parameter vector (length unit, rad).
    exact_xyz : ndarray, shape (N, 3)
        Noise-free tool positions of the true model.
    """

    data: Measurements
    true_params: Array
    exact_xyz: Array

    def __repr__(self) -> str:
        return f"<Simulation {len(self.data.q)} poses, {self.true_params.size} true parameters>"


def random_configurations(
    model: SerialModel, n: int, rng: np.random.Generator, limit: float = np.pi
) -> Array:
    """``(n, n_joints)`` joint values uniform within the model's limits; revolute joints'
    ranges clipped to +-`limit` (rad), prismatic joints' ranges used as they are."""
    lim = np.array(model.joint_limits, dtype=float)
    revolute = ~model.is_prismatic()
    lim[revolute] = np.clip(lim[revolute], -limit, limit)
    return rng.uniform(lim[:, 0], lim[:, 1], size=(n, model.n_joints))


def random_errors(
    model: SerialModel, rng: np.random.Generator, names: list[str] | None = None,
    scale: float = 1.0,
) -> Array:
    """Error vector ``(n_params,)`` uniform within +-tolerance * `scale` on `names`.

    `names` defaults to the model's calibratable parameters; the others stay zero.
    """
    names = list(model.calibratable) if names is None else names
    idx = model.index(names)
    angle = model.is_angle()[idx]
    tol = model.tolerances or {}
    half = np.where(angle, tol["angle"], tol["length"]) * scale
    e = np.zeros(model.n_params)
    e[idx] = rng.uniform(-half, half)
    return e


def simulate(
    model: SerialModel,
    n_poses: int,
    *,
    errors: str | Array | dict = "random",
    noise: float = 0.0,
    rng: int | np.random.Generator | None = None,
    q: Array | None = None,
    orientation: bool = False,
    angle_noise: float = 0.0,
    marker: NDArray[np.intp] | None = None,
) -> Simulation:
    """Measurements of a true arm = `model` + `errors`, at random (or given) poses.

    Parameters
    ----------
    model : SerialModel, str or Path
        Nominal model (a bundled name or a model file / URDF path is loaded).
    n_poses : int
        Number of poses (ignored when `q` is given).
    errors : {"zero", "random"} or ndarray (n_params,) or dict
        True **deviations** from nominal (not absolute values: ``true_params - nominal``):
        none, uniform within the model's tolerances on the calibratable parameters, or
        given (vector, or ``{name: value}`` in length unit / rad). Absolute parameter values
        passed by mistake (the arm would be twice its size) raise the ``absolute-errors``
        warning.
    noise : float
        Standard deviation of the Gaussian noise added to each coordinate (length unit; at
        most the arm's size, `kinecal.calibration.diagnostics.sizes`).
    rng : int or Generator, optional
        Randomness (poses, errors, noise).
    q : ndarray, shape (N, n_joints), optional
        Joint angles to use instead of random ones.
    orientation : bool
        Also measure the tool frame's orientation (a 6-DoF instrument).
    angle_noise : float
        Standard deviation (rad) of the orientation noise, a random rotation vector per pose
        (at most 1 rad).
    marker : ndarray of int, shape (N,), optional
        Models with several markers: the marker each row of `q` measures. Default: every
        configuration is measured at every marker (``N * M`` rows, markers in turn), as a
        tracker measures all reflectors on the flange.
    """
    model = as_model(model)
    gen = np.random.default_rng(rng)
    if q is None:
        if n_poses < 1:
            raise InputError(f"poses: expected a positive number, got {n_poses}", option="--poses")
        q = random_configurations(model, n_poses, gen)
    if not noise >= 0:
        raise InputError(f"noise: expected a standard deviation >= 0, got {noise}",
                         option="--noise")
    if isinstance(errors, str):
        if errors == "zero":
            e = np.zeros(model.n_params)
        elif errors == "random":
            e = random_errors(model, gen)
        else:
            raise InputError(f"errors: expected zero, random or a truth file, got {errors!r}",
                             option="--errors")
    elif isinstance(errors, dict):
        e = np.zeros(model.n_params)
        e[model.index(list(errors))] = list(errors.values())
    else:
        e = np.asarray(errors, dtype=float)
        if e.shape != (model.n_params,):
            raise InputError(f"errors: expected {model.n_params} values, got {e.shape}")
    if not angle_noise >= 0:
        raise InputError(f"angle noise: expected >= 0, got {angle_noise}", option="--angle-noise")
    from kinecal.calibration.diagnostics import sizes  # noise and errors within the machine

    sizes.check_length_noise(noise, sizes.serial_size(model), "--noise", model.length_unit)
    sizes.check_angle_noise(angle_noise, "--angle-noise", f"{angle_noise:.4g} rad")
    sizes.check_deviations(model, e)
    if not isinstance(errors, str):
        from kinecal.calibration.diagnostics.simulate import check_absolute_errors

        check_absolute_errors(model, e)
    true_params = model.nominal + e
    if model.marker_names and marker is None:
        n_markers = len(model.marker_names)
        marker = np.tile(np.arange(n_markers), len(q))
        q = np.repeat(q, n_markers, axis=0)
    T = model.fk(q, true_params, marker)
    exact = T[:, :3, 3]
    xyz = exact + gen.normal(0.0, noise, exact.shape) if noise > 0 else exact.copy()
    rotations = None
    if orientation:
        rotations = T[:, :3, :3]
        if angle_noise > 0:
            turn = matrix_from_axis_angle(gen.normal(0.0, angle_noise, exact.shape))
            rotations = turn @ rotations
    data = Measurements(q, xyz, None, f"simulated {model.name}", rotations, marker,
                        model.marker_names if marker is not None else ())
    return Simulation(data, true_params, exact)


def _angle_scale(model: SerialModel) -> float:
    return 180.0 / np.pi if model.angle_unit == "deg" else 1.0


def write_truth(path: str | Path, model: SerialModel, true_params: Array) -> None:
    """Write a truth file for `true_params` (errors and values in the model file's units)."""
    s = _angle_scale(model)
    angle = model.is_angle()
    conv = np.where(angle, s, 1.0)
    err = (np.asarray(true_params) - model.nominal) * conv
    val = np.asarray(true_params) * conv
    data = {
        "model": model.name,
        "length_unit": model.length_unit,
        "angle_unit": model.angle_unit,
        "errors": {n: float(v) for n, v in zip(model.parameter_names, err, strict=True)},
        "parameters": {n: float(v) for n, v in zip(model.parameter_names, val, strict=True)},
    }
    write_text_atomic(path, json.dumps(data, indent=2) + "\n")


#: length units of truth files and their size in metres
_METRES = {"m": 1.0, "mm": 1e-3}


def read_truth(path: str | Path, model: SerialModel) -> Array:
    """True parameter vector ``(n_params,)`` from a truth file's ``errors`` (angles in its
    ``angle_unit``, lengths in its ``length_unit``, each the model's when absent)."""
    path = Path(path)
    data = read_json(path)
    errors = data.get("errors") if isinstance(data, dict) else None
    if not isinstance(errors, dict):
        raise InputError("expected a truth file with an 'errors' mapping", file=path)
    unit = data.get("angle_unit", model.angle_unit)
    if unit not in ("deg", "rad"):
        raise InputError(f"angle_unit: expected deg or rad, got {unit!r}", file=path)
    length = data.get("length_unit", model.length_unit)
    if length not in _METRES or model.length_unit not in _METRES:
        raise InputError(f"length_unit: expected one of {', '.join(_METRES)}, got {length!r}",
                         file=path)
    f = _METRES[length] / _METRES[model.length_unit]  # the file's lengths in the model's
    s = np.pi / 180.0 if unit == "deg" else 1.0
    p = model.nominal
    angle = model.is_angle()
    for name, value in errors.items():
        if name not in model.parameter_names:
            raise InputError(f"parameter {name!r} is not in model {model.name!r}", file=path)
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(f"errors.{name}: expected a number", file=path) from None
        if isinstance(value, bool) or not np.isfinite(v):
            raise InputError(f"errors.{name}: expected a finite number, got {value!r}",
                             file=path)
        k = model.index([name])[0]
        p[k] += v * s if angle[k] else v * f
    return p
