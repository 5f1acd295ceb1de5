"""Noise levels and error amplitudes a machine of a given size can plausibly have.

A finite number can still be absurd: ``stewart simulate --noise-position 1e300`` wrote
positions of 1e300 m and exited 0. The bound used here is the machine's own size ``L``:

* a length noise (standard deviation per coordinate, of a simulated instrument or the one
  stated with ``calibrate --sigma``) or an error amplitude above ``L`` scatters the
  measured points, or moves the machine's joints, farther than the whole machine extends:
  such data say nothing about its geometry, and no instrument used to calibrate a machine
  is less precise than the machine is large;
* an angular noise above 1 rad (57 deg) is the same bound in angle: it turns a point at
  distance ``L`` by more than ``L``, and (beyond about 1.8 rad) makes the orientation a
  uniformly random one;
* a true deviation of a geometric parameter (``simulate(errors=...)``, ``--errors
  TRUTH.json``) larger than ``L`` for a length, or than half a turn for an angle, is not an
  error of this machine but another machine; so is a model file's ``tolerances`` (how far
  the real machine may be from nominal: the random errors of ``simulate`` and the search
  box of the metaheuristics) beyond the same bounds.

Both are refused (`InputError`, exit 2) before any work. ``L`` is the sum of the arm's
link and tool lengths (`kinecal.kinematics.serial.ik.characteristic_length`, an upper bound of
its reach), and for a Stewart platform its longest leg or the largest distance of a joint
or of the probe tip from the centre (`stewart_size`). The bound is generous on purpose:
it refuses nonsense, not a poor instrument.
"""

from __future__ import annotations

import math

import numpy as np

from kinecal.errors import InputError

__all__ = ["MAX_ANGLE_NOISE", "check_angle_noise", "check_deviations", "check_length_noise",
           "check_tolerances", "serial_size", "stewart_size"]

#: largest plausible angular noise (rad): 1 rad turns a point at the machine's size by
#: the machine's size
MAX_ANGLE_NOISE = 1.0


def serial_size(model) -> float:
    """The size ``L`` of a serial arm: the sum of its absolute link and tool lengths
    (an upper bound of its reach; at least 1 length unit)."""
    from kinecal.kinematics.serial.ik import characteristic_length

    return characteristic_length(model)


def stewart_size(geom) -> float:
    """The size ``L`` of a Stewart platform: its longest leg reading (when bounded), or the
    largest distance of a base joint, a platform joint or the probe tip from its frame's
    origin when larger (length unit of the geometry)."""
    hi = float(geom.leg_range[1])
    sizes = [hi if math.isfinite(hi) else 0.0,
             float(np.linalg.norm(geom.base_joints, axis=1).max()),
             float(np.linalg.norm(geom.platform_joints, axis=1).max()) + abs(geom.probe_offset)]
    return max(sizes)


def check_length_noise(value: float | None, size: float, option: str, unit: str,
                       what: str = "noise standard deviation") -> None:
    """Refuse a length noise or error amplitude larger than the machine's size `size`.

    Parameters
    ----------
    value : float or None
        The value given (None: not given; finiteness and sign are checked elsewhere).
    size : float
        The machine's size ``L`` (`serial_size`, `stewart_size`), same unit.
    option : str
        Where the value was given (named in the error).
    unit : str
        Length unit, for the message.
    what : str
        What the value is, for the message.
    """
    if value is None or not value > size:
        return
    raise InputError(f"a {what} of {value:.4g} {unit} is larger than the whole machine "
                     f"({size:.4g} {unit}), which no measurement or machine of this size has; "
                     f"expected at most {size:.4g} {unit} (is the unit right?)", option=option)


def check_angle_noise(value_rad: float | None, option: str, shown: str) -> None:
    """Refuse an angular noise above `MAX_ANGLE_NOISE` (1 rad); `shown` is the value as the
    user gave it (with its unit), for the message."""
    if value_rad is None or not value_rad > MAX_ANGLE_NOISE:
        return
    raise InputError(f"an orientation noise of {shown} is more than 1 rad (57.3 deg, 206265 "
                     "arcsec): it turns a point at the machine's size by more than the "
                     "machine's size and leaves no information on orientations; expected at "
                     "most 1 rad (is the unit right?)", option=option)


def check_deviations(model, errors, option: str = "--errors") -> None:
    """Refuse true deviations of geometric parameters beyond the machine: a length deviation
    larger than `serial_size`, an angle deviation larger than half a turn (joint-error
    coefficients are not checked here).

    Parameters
    ----------
    model : SerialModel
        The nominal model.
    errors : ndarray, shape (n_params,)
        Deviations from nominal (length unit, rad).
    option : str
        Where they were given (named in the error).
    """
    e = np.asarray(errors, dtype=float)
    n_geo = int(getattr(model, "_n_geometric", model.n_params))
    angle = model.is_angle()[:n_geo]
    size = serial_size(model)
    limit = np.where(angle, np.pi, size)
    bad = np.flatnonzero(~(np.abs(e[:n_geo]) <= limit))
    if bad.size == 0:
        return
    check_tolerances(model)  # random errors within absurd tolerances: name the cause
    k = int(bad[np.argmax(np.abs(e[bad]) / limit[bad])])
    name = model.parameter_names[k]
    if angle[k]:
        deg = model.angle_unit == "deg"
        shown = f"{np.degrees(e[k]):.4g} deg" if deg else f"{e[k]:.4g} rad"
        raise InputError(f"{name} deviates by {shown} from nominal, more than half a turn: "
                         "not an error of this machine but another one (expected deviations "
                         "from nominal, not absolute values)", option=option)
    raise InputError(f"{name} deviates by {e[k]:.4g} {model.length_unit} from nominal, more "
                     f"than the whole machine ({size:.4g} {model.length_unit}): not an error of "
                     "this machine but another one (expected deviations from nominal, not "
                     "absolute values)", option=option)


def check_tolerances(model) -> None:
    """Refuse a model whose ``tolerances`` exceed the machine: a length tolerance larger
    than `serial_size`, an angle tolerance larger than half a turn (a metaheuristic would
    search a box of that size, `simulate` draw errors from it)."""
    tol = model.tolerances or {}
    size = serial_size(model)
    length, angle = float(tol.get("length", 0.0)), float(tol.get("angle", 0.0))
    where = f"model {model.name}: tolerances"
    if not length <= size:
        raise InputError(f"{where}: a length tolerance of {length:.4g} {model.length_unit} "
                         f"is larger than the whole machine ({size:.4g} {model.length_unit}); "
                         "expected how far the real machine may be from nominal (is the unit "
                         "right?)")
    if not angle <= np.pi:
        deg = model.angle_unit == "deg"
        shown = f"{np.degrees(angle):.4g} deg" if deg else f"{angle:.4g} rad"
        raise InputError(f"{where}: an angle tolerance of {shown} is more than half a turn; "
                         "expected how far the real machine may be from nominal (is the unit "
                         "right?)")
