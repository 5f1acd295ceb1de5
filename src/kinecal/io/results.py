"""Calibration result files (JSON) read back: `load_result` for the Python API, and the
helpers the commands that take a result use (``fk --params``, ``export``, ``compensate``,
``iso9283 --params``).

A serial-arm result (``kinecal calibrate --out``) holds the identified value of every
parameter of its model in the model file's units, not the model itself: reading it needs
the nominal model (the bundled model the result names, or the model file or URDF it was
calibrated from). A hand-eye result (``kinecal handeye --out``) holds X and the target
pose; a Stewart-platform result (``kinecal stewart calibrate --out``) the 42 identified
geometry parameters of its nominal geometry.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._files import read_json
from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.stewart.platform import StewartPlatform

__all__ = ["HandEyeResultFile", "SerialResultFile", "StewartResultFile", "load_result",
           "model_for_result", "parameters_from_result", "result_markers",
           "serial_result_parameters"]

Array = NDArray[np.float64]

#: parameters only a Stewart-platform result has
_STEWART_KEYS = {"b1.x", "p1.x"}


def serial_result_parameters(data: object, path: Path) -> dict:
    """The ``parameters`` mapping of a serial-arm calibration result (``calibrate --out``).

    Raises
    ------
    InputError
        A hand-eye or Stewart-platform result (named as such: their JSON is easily passed
        where an arm's result is expected), or JSON without a non-empty ``parameters``.
    """
    params = data.get("parameters") if isinstance(data, dict) else None
    other = None
    if isinstance(data, dict) and "X" in data and params is None:
        other = "a hand-eye calibration result (kinecal handeye)"
    elif isinstance(params, dict) and _STEWART_KEYS <= set(params):
        other = "a Stewart-platform calibration result (kinecal stewart calibrate)"
    if other is not None:
        raise InputError(f"{other}, expected a serial-arm calibration result (kinecal "
                         "calibrate --out)", file=path)
    if not isinstance(params, dict) or not params:
        raise InputError("expected a calibration result (kinecal calibrate --out) with a "
                         "non-empty 'parameters' mapping", file=path)
    return params


def result_markers(params: dict) -> list[str]:
    """Marker names of a result's ``tool.NAME.x`` parameters (several markers)."""
    return [n[5:-2] for n in params if n.startswith("tool.") and n.endswith(".x")
            and n.count(".") >= 2]


def model_for_result(model: SerialModel, path: str | Path) -> SerialModel:
    """`model` with what a result file adds to it: the joint-error terms it declares and
    one tool point per marker when it has several markers."""
    path = Path(path)
    return _model_for_data(model, read_json(path), path)


def _model_for_data(model: SerialModel, data: Any, path: Path) -> SerialModel:
    from kinecal.kinematics.serial.markers import model_for_markers

    params = serial_result_parameters(data, path)
    model = _with_result_joint_errors(model, data, path)
    return model_for_markers(model, result_markers(params))


def parameters_from_result(model: SerialModel, path: str | Path) -> Array:
    """Full parameter vector from a calibration result JSON (``identified`` values, in the
    Python API's units: the model's length unit and radians).

    Refuses (`InputError`) a result without parameters, with a parameter the model does not
    have, a value that is not a finite number, other units, or nominal values that differ
    from the model's (a result of another model). `model` is the model the result
    calibrated, with its markers and joint-error terms (`model_for_result`).
    """
    path = Path(path)
    return _parameters_from_data(model, read_json(path), path)


def _parameters_from_data(model: SerialModel, data: Any, path: Path) -> Array:
    params = serial_result_parameters(data, path)
    for key, mine in (("length_unit", model.length_unit), ("angle_unit", model.angle_unit)):
        theirs = data.get(key)
        if theirs is not None and theirs != mine:
            raise InputError(f"the result's {key} is {theirs!r}, model {model.name!r} uses "
                             f"{mine!r}: a result of another model", file=path)
    angle = model.is_angle()
    scale = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    p = model.nominal
    for name, entry in params.items():
        k = model.index([name])[0] if name in model.parameter_names else None
        if k is None:
            raise InputError(f"parameter {name!r} does not belong to model {model.name!r}",
                             file=path)
        conv = scale if angle[k] else 1.0
        try:
            raw = entry["identified"] if isinstance(entry, dict) else entry
            value = float(raw)
            nominal = float(entry["nominal"]) if isinstance(entry, dict) and entry.get(
                "nominal") is not None else None
        except (KeyError, TypeError, ValueError):
            raise InputError(f"parameter {name!r}: expected a number 'identified'",
                             file=path) from None
        if isinstance(raw, bool) or not np.isfinite(value) or (
                nominal is not None and not np.isfinite(nominal)):
            raise InputError(f"parameter {name!r}: expected a finite number, got {raw!r}",
                             file=path)
        mine = p[k] / conv
        if nominal is not None and abs(nominal - mine) > 1e-6 * max(1.0, abs(mine)):
            raise InputError(f"parameter {name!r} has nominal {nominal:.6g} in the result but "
                             f"{mine:.6g} in model {model.name!r}: a result of another model",
                             file=path)
        p[k] = value * conv
    if "kinecal" in data and isinstance(data.get("free"), list):
        # a result written by calibrate lists every parameter of the chain it calibrated:
        # one without some of this model's is of another chain (a URDF read with other
        # --base-link / --tip-link), whose base frame means something else here
        geometric = model.parameter_names[: getattr(model, "_n_geometric", model.n_params)]
        # an origin's local rotation error (wx, wy, wz) is zero in a result written before
        # origins had one: its roll, pitch and yaw carry the same geometry
        missing = [n for n in geometric if n not in params and not (
            n.rsplit(".", 1)[-1] in ("wx", "wy", "wz") and p[model.index([n])[0]] == 0)]
        if missing:
            raise InputError(
                f"the result has no values for {len(missing)} parameters of model "
                f"{model.name!r} ({', '.join(missing[:4])}{', ...' if len(missing) > 4 else ''})"
                ": it calibrated another chain; give the --base-link / --tip-link (or model) "
                "it was calibrated with", file=path)
    return p


def _with_result_joint_errors(model: SerialModel, data: Any, path: Path) -> SerialModel:
    """`model` with the joint-error terms a calibration result JSON declares (``joint_errors.
    model``, written by ``--error-model``), so that its parameters fit; else `model`."""
    section = data.get("joint_errors")
    if not isinstance(section, dict) or "model" not in section:
        return model
    from kinecal.io.joint_errors_file import joint_errors_from_file

    plain = dataclasses.replace(model, joint_errors=None)
    scale = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    try:
        je = joint_errors_from_file(plain, section["model"], scale)
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    return dataclasses.replace(plain, joint_errors=je)


# ---------------------------------------------------------------------------- load_result
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
                tip_link: str | None = None
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

    Returns
    -------
    SerialResultFile, HandEyeResultFile or StewartResultFile
        By the kind of the result.

    Raises
    ------
    InputError
        Not a result file, a result of another model than `model`, or no `model` where
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
    if isinstance(params, dict) and _STEWART_KEYS <= set(params):
        return _stewart(path, data, model)
    serial_result_parameters(data, path)
    nominal = _serial_model(model, data, path, base_link, tip_link)
    full = _model_for_data(nominal, data, path)
    return SerialResultFile(path, data, full, _parameters_from_data(full, data, path))


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
