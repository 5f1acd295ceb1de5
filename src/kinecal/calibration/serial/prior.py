"""Priors on the free parameters: what the user states, resolved for one calibration.

A prior says, per free parameter ``j``, that its deviation from a prior value ``mu_j``
(the nominal value, or a previous calibration's: ``--prior-from``) is Gaussian with the
1-sigma ``s_j``. The calibration then is a maximum a posteriori (MAP) estimate: the
prior enters the least-squares problem as one extra residual row per parameter,
``sigma_noise (x_j - mu_j) / s_j`` beside the data rows (Tikhonov / ridge regression with
a stated scale; e.g. Hastie, Tibshirani, Friedman, *The Elements of Statistical Learning*,
2nd ed., sec. 3.4.1 and its Bayesian reading, and Kaipio and Somersalo, *Statistical and
Computational Inverse Problems*, 2005, sec. 3.3). How the rows enter the fit is
`prior_fit`; how ``auto`` chooses the strength, `prior_auto`.

Forms (``kinecal calibrate --prior ...``, ``kinecal.calibrate(prior=...)``; sigmas in the
model file's units: the length unit, and degrees for a ``deg`` model):

``auto``
    ``t`` times the model's tolerances on the arm's lengths and angles, ``t`` chosen by
    cross-validation on the calibration poses (no prior when none helps).
``lengths=S,angles=S``
    Groups: every free length / angle of the arm itself (not the set-up: base frame and
    tool points, whose place is arbitrary). A parameter name or a pattern (``tool.*=5``,
    ``theta2=0.1``) states one parameter or a set, any kind; ``none`` for no prior.
a CSV file ``name,sigma[,mean]``
    Per parameter (`kinecal.io.priors`).

Free parameters the prior does not name have none (a flat prior).
"""

from __future__ import annotations

import fnmatch
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.chain import BASE_NAMES
from kinecal.kinematics.serial.model import SerialModel

__all__ = [
    "AUTO",
    "GROUPS",
    "Prior",
    "PriorSpec",
    "is_setup",
    "parse_prior",
    "prior_file",
    "prior_spec",
    "prior_state",
    "prior_text",
    "prior_values",
    "resolve_prior",
    "tolerance_sigma",
]

Array = NDArray[np.float64]

AUTO = "auto"
#: groups of the arm's own parameters, by unit
GROUPS = ("lengths", "angles")
OPTION = "--prior"


def is_setup(name: str) -> bool:
    """True for the measurement set-up's parameters (base frame, tool points, markers)."""
    return name in BASE_NAMES or name.startswith(("base@", "tool."))


@dataclass(frozen=True)
class PriorSpec:
    """A prior as stated, before the free parameters are known.

    Attributes
    ----------
    kind : {"auto", "groups", "file"}
    sigma : dict of str to float or None
        Group, pattern or parameter name -> 1-sigma in the model file's units (None: no
        prior), in the order given.
    means : dict of str to float
        Parameter -> prior value (model file units), from a file.
    source : str or None
        The file, or the groups as written.
    mean_from : str or None
        What the prior values are when not given: None (nominal) or the previous result.
    mean : ndarray, shape (n_params,)
        Prior value of every parameter (length unit, rad).
    """

    kind: str
    sigma: dict[str, float | None]
    means: dict[str, float]
    source: str | None
    mean_from: str | None
    mean: Array


@dataclass
class Prior:
    """A prior resolved for the free parameters of one calibration.

    Attributes
    ----------
    spec : PriorSpec
    names : list of str
        The free parameters.
    mean : ndarray, shape (k,)
        Prior values (length unit, rad).
    sigma : ndarray, shape (k,)
        1-sigma (length unit, rad); ``inf`` where there is no prior.
    strength : float or None
        ``auto``: the chosen multiple of the model's tolerances.
    choice : dict
        ``auto``: the cross-validation table (`prior_auto`).
    """

    spec: PriorSpec
    names: list[str]
    mean: Array
    sigma: Array
    strength: float | None = None
    choice: dict = field(default_factory=dict)

    @property
    def precision(self) -> Array:
        """``1 / sigma^2`` ``(k,)``, 0 where there is no prior."""
        return np.where(np.isfinite(self.sigma), 1.0 / np.square(self.sigma), 0.0)

    @property
    def active(self) -> bool:
        """Some free parameter has a prior."""
        return bool(np.isfinite(self.sigma).any())


def _unit(model: SerialModel) -> Array:
    """Factor from the model file's units to the API's ``(n_params,)``."""
    deg = np.pi / 180.0 if model.angle_unit == "deg" else 1.0
    return np.where(model.is_angle(), deg, 1.0)


def _sigma_value(text: Any, key: str) -> float | None:
    if text is None or (isinstance(text, str) and text.strip().lower() in ("none", "inf")):
        return None
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise InputError(f"{key}: expected a 1-sigma (a positive number) or none, got "
                         f"{text!r}", option=OPTION) from None
    if value == float("inf"):
        return None
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"{key}: expected a positive 1-sigma (or none), got {text!r}",
                         option=OPTION)
    return value


def _check_key(model: SerialModel, key: str) -> None:
    if key in GROUPS or key in model.parameter_names:
        return
    if any(c in key for c in "*?[") and fnmatch.filter(model.parameter_names, key):
        return
    raise InputError(f"unknown group {key!r}: expected {', '.join(GROUPS)}, a parameter of "
                     f"model {model.name!r} or a pattern of them (tool.*)", option=OPTION)


def _groups(model: SerialModel, items: Mapping[str, Any]) -> dict[str, float | None]:
    out: dict[str, float | None] = {}
    for key, value in items.items():
        key = str(key).strip()
        _check_key(model, key)
        if key in out:
            raise InputError(f"{key} is given twice", option=OPTION)
        out[key] = _sigma_value(value, key)
    if not out:
        raise InputError("expected auto, groups such as lengths=0.5,angles=0.05, or a CSV "
                         "file name,sigma[,mean]", option=OPTION)
    return out


def _group_text(text: str) -> dict[str, str]:
    items: dict[str, str] = {}
    for part in text.split(","):
        if not part.strip():
            continue
        key, sep, value = part.partition("=")
        if not sep:
            raise InputError(f"{part.strip()!r}: expected GROUP=SIGMA (lengths=0.5)",
                             option=OPTION)
        if key.strip() in items:
            raise InputError(f"{key.strip()} is given twice", option=OPTION)
        items[key.strip()] = value
    return items


def prior_state(spec: PriorSpec | None, fit: object) -> str | None:
    """What the plausibility messages say of the prior: None (none asked for), ``"used"``
    or ``"declined"`` (asked for, but it decides nothing: ``auto`` chose none)."""
    if spec is None:
        return None
    return "declined" if fit is None else "used"


def prior_file(prior: Any) -> str | Path | None:
    """The file a ``--prior`` value names (None for ``auto`` and groups)."""
    if isinstance(prior, Path) or (isinstance(prior, str) and prior.strip() != AUTO
                                   and "=" not in prior):
        return prior
    return None


def prior_values(model: SerialModel, prior_from: Any) -> tuple[Array, str | None]:
    """Prior value of every parameter ``(n_params,)`` (length unit, rad) and its label:
    the nominal values, or those of a previous result (a result JSON path, a result
    object, or a parameter vector), matched by name."""
    if prior_from is None:
        return model.nominal, None
    if isinstance(prior_from, str | Path):
        from kinecal.io.results import load_result

        prior_from = load_result(prior_from, model)
        label = str(prior_from.path)
    else:
        label = "a previous result"
    if isinstance(prior_from, np.ndarray | list | tuple):
        p = np.asarray(prior_from, dtype=float)
        if p.shape != (model.n_params,) or not np.isfinite(p).all():
            raise InputError(f"prior_from: expected {model.n_params} finite parameter values",
                             option="--prior-from")
        return p, "given values"
    theirs = getattr(prior_from, "nominal_model", None)
    if theirs is None:
        raise TypeError("prior_from: expected a result JSON path, a calibration result or "
                        f"a parameter vector, got {type(prior_from).__name__}")
    values = dict(zip(theirs.parameter_names, np.asarray(prior_from.params, float).tolist(),
                      strict=True))
    p = model.nominal
    for k, name in enumerate(model.parameter_names):
        if name in values:
            p[k] = values[name]
    return p, label


def parse_prior(model: SerialModel, prior: Any, prior_from: Any = None) -> PriorSpec | None:
    """A `PriorSpec` from what the user gave (module docstring); None for no prior.

    `prior_from` alone means ``auto`` about the previous result's values.

    Raises
    ------
    InputError
        Unknown group or parameter, a sigma that is not positive, a bad file.
    """
    if prior is None and prior_from is None:
        return None
    if isinstance(prior, PriorSpec):
        return prior
    mean, label = prior_values(model, prior_from)
    if prior is None or (isinstance(prior, str) and prior.strip() == AUTO):
        return PriorSpec(AUTO, {}, {}, None, label, mean)
    if isinstance(prior, Mapping):
        items = {k: (v[0] if isinstance(v, tuple | list) else v) for k, v in prior.items()}
        means = {str(k): float(v[1]) for k, v in prior.items()
                 if isinstance(v, tuple | list) and len(v) > 1 and v[1] is not None}
        for name in means:
            if name not in model.parameter_names:
                raise InputError(f"{name}: a prior value needs a parameter name",
                                 option=OPTION)
        return _with_means(model, PriorSpec("groups", _groups(model, items), means, None,
                                            label, mean))
    if isinstance(prior, str) and "=" in prior:
        return PriorSpec("groups", _groups(model, _group_text(prior)), {}, prior.strip(),
                         label, mean)
    if isinstance(prior, str | Path):
        from kinecal.io.priors import read_prior_file

        if not Path(prior).exists():
            raise InputError(f"{str(prior)!r}: expected auto, groups GROUP=SIGMA "
                             "(lengths=0.5,angles=0.05) or a CSV file name,sigma[,mean]; no "
                             "such file", option=OPTION)

        rows = read_prior_file(prior, model)
        sigma = {r.name: r.sigma for r in rows}
        means = {r.name: r.mean for r in rows if r.mean is not None}
        return _with_means(model, PriorSpec("file", sigma, means, str(prior), label, mean))
    raise TypeError(f"prior: expected 'auto', groups ('lengths=0.5,angles=0.05' or a dict), "
                    f"a CSV path or a PriorSpec, got {type(prior).__name__}")


def prior_spec(model: SerialModel, prior: Any, prior_from: Any, method: str,
               loss: str) -> PriorSpec | None:
    """`parse_prior`, refused up front where a prior cannot enter: a solver other than
    Levenberg-Marquardt (the prior rows are least-squares rows) or a robust loss (which
    would bend the prior rows too)."""
    if prior is None and prior_from is None:
        return None
    if method != "lm":
        raise InputError(f"a prior needs --method lm (its rows are least-squares rows), got "
                         f"{method}", option=OPTION)
    if loss != "linear":
        raise InputError(f"a prior needs --loss linear (a robust loss would bend the prior's "
                         f"rows too), got {loss}", option=OPTION)
    return parse_prior(model, prior, prior_from)


def _with_means(model: SerialModel, spec: PriorSpec) -> PriorSpec:
    """`spec` with its stated prior values put into its ``mean`` vector."""
    if not spec.means:
        return spec
    mean = spec.mean.copy()
    idx = model.index(list(spec.means))
    mean[idx] = np.array(list(spec.means.values())) * _unit(model)[idx]
    if not np.isfinite(mean).all():
        raise InputError("prior values: expected finite numbers", option=OPTION)
    return PriorSpec(spec.kind, spec.sigma, spec.means, spec.source, spec.mean_from, mean)


def tolerance_sigma(model: SerialModel, names: list[str]) -> Array:
    """The shape ``auto`` scales ``(k,)``: the model's tolerance of each arm parameter
    (length unit, rad), ``inf`` for the set-up and joint-error coefficients."""
    idx = model.index(names)
    angle = model.is_angle()[idx]
    tol = np.where(angle, model.tolerances["angle"], model.tolerances["length"])
    geometric = idx < getattr(model, "_n_geometric", model.n_params)
    arm = np.array([not is_setup(n) for n in names], dtype=bool) & geometric
    return np.where(arm, tol, np.inf)


def resolve_prior(model: SerialModel, spec: PriorSpec, names: list[str],
                  strength: float | None = None) -> Prior:
    """The prior of the free parameters `names` (a parameter named by the spec but not
    free is left out). ``auto`` needs `strength` (the multiple of the tolerances)."""
    idx = model.index(names)
    mean = spec.mean[idx].copy()
    if spec.kind == AUTO:
        sigma = (np.full(len(names), np.inf) if strength is None
                 else tolerance_sigma(model, names) * strength)
        return Prior(spec, list(names), mean, sigma, strength)
    unit = _unit(model)[idx]
    angle = model.is_angle()[idx]
    geometric = idx < getattr(model, "_n_geometric", model.n_params)
    sigma = np.full(len(names), np.inf)
    for j, n in enumerate(names):
        value, found = None, False
        if n in spec.sigma:  # a parameter's own entry first
            value, found = spec.sigma[n], True
        else:
            for key, v in spec.sigma.items():
                if key not in GROUPS and fnmatch.fnmatchcase(n, key):
                    value, found = v, True
                    break
        if not found and geometric[j] and not is_setup(n):
            value = spec.sigma.get("angles" if angle[j] else "lengths")
        if value is not None:
            sigma[j] = value * unit[j]
    return Prior(spec, list(names), mean, sigma)


def prior_text(model: SerialModel, prior: Prior) -> str:
    """``lengths=0.25,angles=0.05`` for ``auto`` (model file units), or the spec as given."""
    if prior.spec.kind == AUTO:
        if prior.strength is None:
            return "none"
        t = prior.strength
        ang = model.tolerances["angle"] * (180.0 / np.pi if model.angle_unit == "deg" else 1.0)
        return f"lengths={t * model.tolerances['length']:.4g},angles={t * ang:.4g}"
    if prior.spec.kind == "file":
        return str(prior.spec.source)
    return ",".join(f"{k}={'none' if v is None else f'{v:g}'}"
                    for k, v in prior.spec.sigma.items())
