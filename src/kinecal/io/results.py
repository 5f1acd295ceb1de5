"""Calibration result files (JSON) read back into objects: `load_result` (``kinecal.load_result``)
for serial-arm (``kinecal calibrate --out``), hand-eye (``kinecal handeye --out``) and
Stewart-platform (``kinecal stewart calibrate --out``) results.

A serial-arm result is read with its nominal model (`kinecal.io.result_values`): the
bundled model the result names, or the model file or URDF it was calibrated from. A
hand-eye result holds X and the target pose; a Stewart-platform result the 42 identified
geometry parameters of its nominal geometry.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._files import read_json
from kinecal.errors import InputError
from kinecal.io.result_values import (
    STEWART_KEYS,
    model_for_data,
    parameters_from_data,
    result_envelope,
    serial_result_parameters,
)
from kinecal.kinematics.serial.joint_errors_envelope import JointEnvelope
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.stewart.platform import StewartPlatform

__all__ = ["HandEyeResultFile", "SerialResultFile", "StewartResultFile", "load_result"]

Array = NDArray[np.float64]


@dataclass(frozen=True, repr=False)
class SerialResultFile:
    """A serial-arm calibration result read from its JSON (`load_result`).

    Usable where a `CalibrationResult` is: `kinecal.compensate(res, joints=q)`, and like
    ``fk --params`` (``res.model.positions(q)``, or ``res.nominal_model.positions(q,
    res.params)``); `save_model` writes the calibrated model file (``export --format
    yaml``).

    Attributes
    ----------
    path : Path
        The JSON file.
    data : dict
        Its content (lengths in the model's unit, angles in its angle unit).
    nominal_model : SerialModel
        The model calibrated from, with the result's markers and joint-error terms.
    params : ndarray, shape (n_params,)
        Identified parameter vector (model length unit, radians).
    """

    path: Path
    data: dict
    nominal_model: SerialModel
    params: Array

    @property
    def model(self) -> SerialModel:
        """The calibrated model (``NAME-calibrated``)."""
        return self.nominal_model.with_params(self.params,
                                              name=f"{self.nominal_model.name}-calibrated")

    @property
    def length_unit(self) -> str:
        return self.nominal_model.length_unit

    @property
    def free(self) -> list[str]:
        """The identified (free) parameters."""
        free = self.data.get("free")
        if isinstance(free, list):
            return [str(n) for n in free]
        return [n for n, e in self.data["parameters"].items()
                if isinstance(e, dict) and e.get("free")]

    @property
    def std(self) -> Array:
        """Standard errors ``(n_params,)`` (length unit, rad): 0 for held parameters, inf
        for free ones without a standard error (``null`` in the file)."""
        model = self.nominal_model
        scale = np.where(model.is_angle(), np.pi / 180.0 if model.angle_unit == "deg" else 1.0,
                         1.0)
        out = np.zeros(model.n_params)
        for name, entry in self.data["parameters"].items():
            if isinstance(entry, dict) and name in model.parameter_names:
                k = model.index([name])[0]
                s = entry.get("std")
                out[k] = np.inf if s is None else float(s) * scale[k]
        return out

    @property
    def warnings(self) -> list[dict]:
        return list(self.data.get("warnings") or [])

    @property
    def envelope(self) -> JointEnvelope | None:
        """The joint readings the calibration saw (the file's ``envelope``; None in a
        result written before results stored it)."""
        return result_envelope(self.nominal_model, self.data, self.path)

    def save_model(self, path: str | Path) -> None:
        """Write the calibrated model file (read back by `kinecal.load_model`)."""
        from kinecal.io.models import save_model

        save_model(self.model, path)

    def __repr__(self) -> str:
        d = self.data
        val = (d.get("validation") or d.get("calibration") or {}).get("after") or {}
        mean = val.get("mean")
        where = "validation" if d.get("validation") else "calibration"
        return (f"<SerialResultFile {self.path.name}: model {self.nominal_model.name}, "
                f"{len(self.free)} free parameters"
                + (f", {where} mean {mean:.4g} {self.length_unit}" if mean is not None else "")
                + ">")


@dataclass(frozen=True, repr=False)
class HandEyeResultFile:
    """A hand-eye calibration result read from its JSON (`load_result`).

    Attributes
    ----------
    path : Path
    data : dict
    X : ndarray, shape (4, 4)
        ``cam2flange`` (eye-in-hand) or ``cam2base`` (eye-to-hand).
    target : ndarray, shape (4, 4) or None
        ``target2base`` (eye-in-hand) or ``target2flange`` (eye-to-hand).
    setup : str
    length_unit : str
        The unit of the translations (``input unit`` when the file does not say).
    """

    path: Path
    data: dict
    X: Array
    target: Array | None
    setup: str
    length_unit: str

    def __repr__(self) -> str:
        t = self.X[:3, 3]
        return (f"<HandEyeResultFile {self.path.name}: {self.setup}, X translation "
                f"({t[0]:.4g}, {t[1]:.4g}, {t[2]:.4g}) {self.length_unit}>")


@dataclass(frozen=True, repr=False)
class StewartResultFile:
    """A Stewart-platform calibration result read from its JSON (`load_result`).

    ``res.geometry.inverse(poses)`` gives the legs that put the real machine at `poses`
    (the machine's compensation, as ``kinecal stewart ik`` with ``--geometry-out``).

    Attributes
    ----------
    path : Path
    data : dict
    nominal : StewartPlatform
        The geometry calibrated from.
    geometry : StewartPlatform
        The calibrated geometry (identified joints and leg offsets).
    length_unit : str
    """

    path: Path
    data: dict
    nominal: StewartPlatform
    geometry: StewartPlatform
    length_unit: str

    def __repr__(self) -> str:
        return (f"<StewartResultFile {self.path.name}: geometry {self.nominal.name}, "
                f"rank {self.data.get('rank')}, {self.length_unit}>")


def load_result(path: str | Path, model: Any = None, *, base_link: str | None = None,
                tip_link: str | None = None, check: bool = True
                ) -> SerialResultFile | HandEyeResultFile | StewartResultFile:
    """Read a calibration result JSON written by kinecal.

    Parameters
    ----------
    path : str or Path
        A result of ``kinecal calibrate --out`` (or `CalibrationResult.to_json`, ``kinecal
        demo``), ``kinecal handeye --out`` or ``kinecal stewart calibrate --out``.
    model : SerialModel, StewartPlatform, str or Path, optional
        The model the result calibrated: a model, a bundled name or a model file / URDF
        path (serial arm), or a geometry or geometry name / path (Stewart platform).
        Default: the bundled model or geometry the result names; needed for a model file
        of your own or a URDF (whose robot name is not a file). Not used for hand-eye.
    base_link, tip_link : str, optional
        The chain of a URDF `model` given as a path, as calibrated.
    check : bool
        Serial arm: refuse identified values that make another arm than the nominal one
        (the same-arm rule of ``fk --params``, ``export`` and ``compensate``,
        `kinecal.kinematics.serial.same_arm`; the calibration warned about such a result
        as ``implausible-change``). False reads it anyway, to inspect it.

    Returns
    -------
    SerialResultFile, HandEyeResultFile or StewartResultFile
        By the kind of the result.

    Raises
    ------
    InputError
        Not a result file, a result of another model than `model` (other parameters or
        nominal values, or identified values that make another arm), or no `model` where
        the result names none that is bundled.
    TypeError
        `model` of another type than those above.
    """
    path = Path(path)
    data = read_json(path)
    if not isinstance(data, dict):
        raise InputError("expected a calibration result (a JSON object)", file=path)
    params = data.get("parameters")
    if "X" in data and params is None:
        return _handeye(path, data)
    if isinstance(params, dict) and STEWART_KEYS <= set(params):
        return _stewart(path, data, model)
    serial_result_parameters(data, path)
    nominal = _serial_model(model, data, path, base_link, tip_link)
    full = model_for_data(nominal, data, path)
    params = parameters_from_data(full, data, path)
    if check:
        _check_same_arm(full, params, path)
    out = SerialResultFile(path, data, full, params)
    _ = out.envelope  # a malformed envelope is refused at once
    return out


def _check_same_arm(model: SerialModel, params: Array, path: Path) -> None:
    """Refuse a result whose identified values make another arm than `model`: the rule of
    ``fk --params``, ``export`` and ``compensate`` (and of the calibration's
    ``implausible-change`` warning), `kinecal.kinematics.serial.same_arm.compare_arms`."""
    from kinecal.kinematics.serial.same_arm import check_same_arm

    try:
        check_same_arm(model, model.with_params(params, name=f"{model.name}-calibrated"))
    except InputError as exc:
        raise InputError(exc.message + " (load_result(..., check=False) reads it anyway, "
                         "to inspect it)", file=path) from None


def _serial_model(model: Any, data: dict, path: Path, base_link: str | None,
                  tip_link: str | None) -> SerialModel:
    from kinecal.io.models import bundled_models, load_model

    if isinstance(model, SerialModel):
        if base_link is not None or tip_link is not None:
            raise TypeError("base_link and tip_link choose the chain of a URDF path; the "
                            "model given is already loaded")
        return model
    if model is None:
        named = data.get("model")
        if not (isinstance(named, str) and named in bundled_models()):
            raise InputError(f"the result is for model {named!r}, not a bundled one: give "
                             "model= (the model file or URDF it was calibrated from)",
                             file=path)
        model = named
    if not isinstance(model, str | Path):
        raise TypeError(f"model: expected a SerialModel, a bundled model name or a model "
                        f"file path, got {type(model).__name__}")
    return load_model(model, base_link=base_link, tip_link=tip_link)


def _handeye(path: Path, data: dict) -> HandEyeResultFile:
    from kinecal.spatial import check_transform

    try:
        X = check_transform(np.asarray(data["X"], dtype=float), name="X")
        target = data.get("target")
        Y = None if target is None else check_transform(np.asarray(target, dtype=float),
                                                        name="target")
    except (TypeError, ValueError) as exc:
        msg = exc.message if isinstance(exc, InputError) else "expected a 4x4 matrix"
        raise InputError(f"X, target: {msg}", file=path) from None
    return HandEyeResultFile(path, data, X, Y, str(data.get("setup", "eye-in-hand")),
                             str(data.get("length_unit") or "input unit"))


def _stewart(path: Path, data: dict, model: Any) -> StewartResultFile:
    from kinecal.io.geometry import bundled_geometries, load_geometry
    from kinecal.kinematics.stewart.platform import PARAMETER_NAMES

    if isinstance(model, StewartPlatform):
        nominal = model
    elif model is None or isinstance(model, str | Path):
        if model is None:
            named = data.get("model")
            if named not in bundled_geometries():
                raise InputError(f"the result is for geometry {named!r}, not a bundled one: "
                                 "give model= (the geometry file it was calibrated from)",
                                 file=path)
            model = named
        nominal = load_geometry(model)
    else:
        raise TypeError(f"model: expected a StewartPlatform, a bundled geometry name or a "
                        f"geometry file path, got {type(model).__name__}")
    params = data["parameters"]
    values = []
    for k, name in enumerate(PARAMETER_NAMES):
        entry = params.get(name)
        try:
            value = float(entry["identified"])
            nom = float(entry["nominal"])
        except (KeyError, TypeError, ValueError):
            raise InputError(f"parameter {name!r}: expected numbers 'nominal' and "
                             "'identified'", file=path) from None
        if not (np.isfinite(value) and np.isfinite(nom)):
            raise InputError(f"parameter {name!r}: expected finite numbers", file=path)
        mine = nominal.parameters[k]
        if abs(nom - mine) > 1e-9 * max(1.0, abs(mine)):
            raise InputError(f"parameter {name!r} has nominal {nom:.9g} in the result but "
                             f"{mine:.9g} in geometry {nominal.name!r}: a result of another "
                             "geometry", file=path)
        values.append(value)
    return StewartResultFile(path, data, nominal, nominal.with_parameters(values),
                             str(data.get("length_unit") or "m"))
