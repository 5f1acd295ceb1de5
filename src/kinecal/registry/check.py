"""The check: is a robot's current calibration still valid? (``kinecal check``).

A few poses measured today (5 to 20, any measurement kind: `kinecal.io.kinds`) are
predicted by the calibration; each set's own unknowns (a ballbar's pivot, a plane) are
fitted with the arm held at the calibration, and the base frame too when it is to be
registered again (the instrument was set up elsewhere). The residuals are judged by
`kinecal.registry.check_stats` against the calibration's own uncertainty (the covariance
of its free parameters, stored in its result) and the instrument's noise (each set's
stated noise, else the calibration's for that kind). The verdict:

``valid`` (exit 0)
    Neither test finds a change at the false-alarm probability ``alpha``.
``drifted`` (exit 3)
    A change is found, and the systematic error it makes (``deviation``, RMS per
    observation) is within the limit.
``recalibrate`` (exit 4)
    A change is found and its systematic error exceeds the limit.

The limit (``--limit``, length unit) defaults to twice the calibration's RMS error after
calibration (its validation's when it had one).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.serial.model import SerialModel

__all__ = ["ALPHA", "EXIT_CODES", "MAX_POSES", "MIN_POSES", "Calibrated", "CheckResult",
           "calibrated_from_result", "drift_directions", "run_check"]

Array = NDArray[np.float64]

#: exit status of each verdict
EXIT_CODES = {"valid": 0, "drifted": 3, "recalibrate": 4}
#: default probability that an unchanged robot is found changed, per check: a robot is
#: checked many times in its life and every false alarm stops it, so the default keeps a
#: monthly check over two years (24 checks) below 0.25 % of false alarms; a change at the
#: limit stands many standard errors out of the noise (plan-check says how many), so the
#: small alpha costs little where it matters (benchmarks/bench_registry.py: 1e-3 and 1e-4)
ALPHA = 1e-4
#: poses a check takes (observations of all its files)
MIN_POSES, MAX_POSES = 5, 200
#: the default limit, in RMS errors of the calibration
LIMIT_FACTOR = 2.0
#: ``check-base-moved`` when a base move, significant on its own, explains this share of
#: today's change
BASE_SHARE = 0.8


@dataclass
class Calibrated:
    """A calibration ready to be checked.

    Attributes
    ----------
    model : SerialModel
        The model it calibrated (with its markers and joint-error terms).
    params : ndarray, shape (n_params,)
        Identified values (API units: length unit, radians).
    free : list of str
        Its free parameters.
    covariance : ndarray, shape (k, k)
        Their covariance (API units); rows and columns of parameters without a finite
        variance are zero and the parameters listed in `unbounded`.
    unbounded : list of str
        Free parameters the calibration did not determine (treated as unknown today).
    noise : dict
        Default 1-sigma noise per measurement kind (length unit).
    noise_dof : float or None
        Degrees of freedom of that noise when it was estimated from the calibration's
        residual (None: stated, known).
    rms : float or None
        RMS error after calibration (validation's if any), for the default limit.
    data : dict
        The result JSON.
    """

    model: SerialModel
    params: Array
    free: list[str]
    covariance: Array
    unbounded: list[str]
    noise: dict[str, float]
    noise_dof: float | None
    rms: float | None
    data: dict[str, Any]


def _covariance(model: SerialModel, data: dict, free: list[str], where: Path) -> Array:
    """The free parameters' covariance (API units) from the result (a diagonal of its
    standard errors when it has no matrix: a result of an older kinecal)."""
    angle = model.is_angle()[model.index(free)] if free else np.zeros(0, bool)
    conv = np.where(angle, np.pi / 180.0 if model.angle_unit == "deg" else 1.0, 1.0)
    table = data.get("covariance")
    if isinstance(table, dict) and table.get("parameters") == free:
        try:
            C = np.array([[np.nan if v is None else float(v) for v in row]
                          for row in table["matrix"]], dtype=float)
        except (TypeError, ValueError, KeyError):
            raise InputError("covariance: expected a matrix of numbers", file=where) from None
        if C.shape != (len(free), len(free)):
            raise InputError(f"covariance: expected {len(free)} x {len(free)}, got "
                             f"{C.shape}", file=where)
    else:
        std = [data["parameters"][n].get("std") for n in free]
        C = np.diag([np.nan if s is None else float(s) ** 2 for s in std])
    return C * np.outer(conv, conv)


def _noise(data: dict) -> tuple[dict[str, float], float | None, float]:
    """The calibration's noise per kind, the degrees of freedom of its estimate (None:
    stated) and the factor that turns its covariance into the known-noise one."""
    out: dict[str, float] = {}
    kinds = [e for e in data.get("kinds") or [] if isinstance(e, dict)]
    for entry in kinds:
        if entry.get("sigma") and entry.get("kind") not in out:
            out[str(entry["kind"])] = float(entry["sigma"])
    noise = data.get("noise") if isinstance(data.get("noise"), dict) else {}
    estimated = data.get("sigma")
    stated = noise.get("stated_sigma")
    if stated is not None and estimated:  # the stated noise, with its covariance
        out.setdefault("tracker", float(stated))
        return out, None, (float(stated) / float(estimated)) ** 2
    if "tracker" not in out and estimated is not None and np.isfinite(float(estimated)):
        out["tracker"] = float(estimated)
    if kinds and all(e.get("sigma_source") == "stated" for e in kinds):
        return out, None, 1.0
    rows = sum(int(e.get("rows") or 0) for e in kinds) if kinds else 3 * int(
        (data.get("calibration") or {}).get("n") or 0)
    dof = rows - int(data.get("rank") or 0)
    return out, (float(dof) if dof > 0 else None), 1.0


def _rms(data: dict) -> float | None:
    for key in ("validation", "calibration"):
        part = data.get(key)
        if isinstance(part, dict) and isinstance(part.get("after"), dict):
            value = part["after"].get("rms")
            if value is not None:
                return float(value)
    return None


def calibrated_from_result(model: SerialModel, data: dict, where: str | Path) -> Calibrated:
    """A calibration result (its JSON as a dict) on its nominal `model`, ready to check."""
    from kinecal.io.result_values import model_for_data, parameters_from_data

    where = Path(where)
    model = model_for_data(model, data, where)
    params = parameters_from_data(model, data, where)
    free = [str(n) for n in data.get("free") or []]
    if not free:
        raise InputError("the result names no free parameters: not a calibration to check",
                         file=where)
    noise, dof, known = _noise(data)
    C = _covariance(model, data, free, where) * known
    bad = ~np.isfinite(np.diag(C)) | ~np.isfinite(C).all(axis=1)
    C[bad, :] = 0.0
    C[:, bad] = 0.0
    return Calibrated(model, params, free, C, [n for n, b in zip(free, bad, strict=True) if b],
                      noise, dof, _rms(data), data)


def drift_directions(model: SerialModel) -> list[str]:
    """The changes robots usually suffer, as parameters: each joint's offset (its zero)
    and the base frame's six (the robot moved on its mount)."""
    offsets = []
    k = 0
    for entry in model.joints:
        if "frame" in entry:
            continue
        k += 1
        if model.convention == "urdf":
            name = f"{entry.get('name')}.offset"
        else:
            name = f"{'d' if entry.get('type') == 'prismatic' else 'theta'}{k}"
        if name in model.parameter_names:
            offsets.append(name)
    return offsets + [f"base.{c}" for c in ("x", "y", "z", "rx", "ry", "rz")]


@dataclass
class CheckResult:
    """A check's findings (`run_check`); `to_dict` is the ``--json`` output."""

    verdict: str
    statistic: float
    dof: int
    noise_dof: float | None
    p_value: float
    alpha: float
    limit: float
    deviation: float
    directed: dict[str, Any]
    poses: list[dict[str, Any]]
    directions: dict[str, dict[str, float]]
    noise: dict[str, float]
    register: bool
    length_unit: str
    base_registered: str | None = None
    warnings: list[dict[str, str]] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """0 valid, 3 drifted, 4 recalibrate."""
        return EXIT_CODES[self.verdict]

    def to_dict(self) -> dict[str, Any]:
        """``{"verdict", "statistic", "p_value", "limit", "poses", ...}``."""
        return {
            "verdict": self.verdict, "statistic": self.statistic, "dof": self.dof,
            "p_value": self.p_value, "limit": self.limit, "deviation": self.deviation,
            "alpha": self.alpha, "test": (
                "chi-square" if self.noise_dof is None else "F") + " test of the residuals "
            "whitened by the calibration's prediction covariance and the instrument's noise",
            "noise_dof": self.noise_dof,
            "directed": self.directed, "directions": self.directions, "noise": self.noise,
            "register_base": self.register, "base_registered": self.base_registered,
            "length_unit": self.length_unit,
            "poses": self.poses, "warnings": self.warnings,
        }


def run_check(cal: Calibrated, data: list, *, sigma: list[float | None] | None = None,
              limit: float | None = None, alpha: float = ALPHA,
              register_base: bool = False) -> CheckResult:
    """Check `cal` against today's measurement sets `data` (module docstring).

    Parameters
    ----------
    cal : Calibrated
        The calibration (`calibrated_from_result`).
    data : list of Measurements or GaugeMeasurements
        Today's sets (`kinecal.io.kinds.read_kind`).
    sigma : list of float or None, optional
        Stated noise per set (None: the set's ``sigma`` column, else the calibration's
        noise for its kind).
    limit : float, optional
        Largest acceptable systematic error (length unit; module docstring).
    alpha : float
        False-alarm probability of the tests.
    register_base : bool
        Fit the base frame to today's data (the instrument moved): base changes are then
        not judged. Done anyway, and said (``base_registered``), when the calibration did
        not determine the base frame of a model that has one (stations, gauges) and today's
        data are tracker points: their frame is unknown to it.
    """
    from kinecal.calibration.blocks.make import make_blocks, marker_names
    from kinecal.kinematics.serial.markers import model_for_markers
    from kinecal.registry.check_fit import fit_rows
    from kinecal.registry.check_stats import judge

    if not 0 < alpha < 0.5:
        raise InputError(f"expected 0 < alpha < 0.5, got {alpha}", option="--alpha")
    model = model_for_markers(cal.model, marker_names(data))
    blocks = make_blocks(model, data, sigma)
    n_obs = sum(b.n_obs for b in blocks)
    if not MIN_POSES <= n_obs <= MAX_POSES:
        raise InputError(f"{n_obs} measured poses: a check takes {MIN_POSES} to {MAX_POSES} "
                         "(kinecal plan-check chooses them)", option="FEW.csv")
    noise = [_block_noise(b, cal) for b in blocks]
    # the calibration's estimated noise scales C and the noise alike: F tests
    estimated = any(b.stated_sigma() is None for b in blocks)
    noise_dof = cal.noise_dof if estimated else None
    limit = _limit(limit, cal)
    undetermined = (model.base is not None and not register_base
                    and not any(n.startswith("base.") for n in cal.free)
                    and any(b.kind == "tracker" for b in blocks))
    register_base = register_base or undetermined
    directions = [] if register_base else drift_directions(model)
    rows = fit_rows(model, cal, blocks, noise, directions, register_base)
    base = np.array([k for k, n in enumerate(directions) if n.startswith("base.")], np.intp)
    j = judge(rows.r, rows.s, rows.A, cal.covariance, rows.N, rows.D, rows.obs, n_obs, alpha,
              noise_dof, {"base": base})
    if j.changed and j.explained.get("base", 0.0) > BASE_SHARE and \
            j.explained_p["base"] < alpha / 2:
        _warn_base_moved(model, directions, -j.change, j.change_std, j.explained["base"])
    verdict = "valid" if not j.changed else ("recalibrate" if j.deviation > limit
                                             else "drifted")
    poses = _poses(blocks, rows, j.expected, cal)
    return CheckResult(
        verdict, j.statistic, j.dof, noise_dof, j.p_value, alpha, limit, j.deviation,
        {"statistic": j.directed_statistic, "dof": j.directed_dof,
         "p_value": j.directed_p_value, "directions": [directions[k] for k in
                                                       np.flatnonzero(np.isfinite(j.change))]},
        poses, _direction_table(model, directions, -j.change, j.change_std),
        {(Path(b.source).name or b.kind): float(np.median(n))
         for b, n in zip(blocks, noise, strict=True)},
        register_base, model.length_unit,
        base_registered="the calibration did not determine the base frame" if undetermined
        else ("asked for" if register_base else None))


def _warn_base_moved(model: SerialModel, names: list[str], change: Array, std: Array,
                     share: float) -> None:
    """``check-base-moved``: today's change is mostly a move of the base frame."""
    from kinecal.diagnostics import warn

    idx = [k for k, n in enumerate(names) if n.startswith("base.") and np.isfinite(change[k])]
    move = np.linalg.norm([change[k] for k in idx if names[k][-1] in "xyz" and
                           not names[k].endswith(("rx", "ry", "rz"))]) if idx else 0.0
    turn = np.degrees(np.linalg.norm([change[k] for k in idx if names[k].endswith(
        ("rx", "ry", "rz"))])) if idx else 0.0
    warn("check-base-moved",
         f"{100 * min(share, 1.0):.0f} % of today's change is a move of the base frame "
         f"({move:.3g} {model.length_unit}, {turn:.3g} deg): if the instrument was set up "
         "elsewhere since the calibration, check again with --register base; if the robot "
         "moved on its mount, recalibrate (its base at least)")


def _block_noise(block: Any, cal: Calibrated) -> Array:
    """1-sigma noise of each observation of `block`: stated, else the calibration's."""
    stated = block.stated_sigma()
    if stated is not None:
        return np.asarray(stated, dtype=float)
    sigma = cal.noise.get(block.kind)
    if sigma is None:
        raise InputError(f"{block.name}: no noise stated and the calibration has none for "
                         f"{block.kind} measurements: give --sigma (the instrument's 1-sigma "
                         "noise, length unit) or a sigma column", option="--sigma")
    return sigma * block.relative_sigma()


def _limit(limit: float | None, cal: Calibrated) -> float:
    if limit is None:
        if cal.rms is None:
            raise InputError("the calibration has no RMS error to derive a limit from: give "
                             "--limit", option="--limit")
        return LIMIT_FACTOR * cal.rms
    if not (np.isfinite(limit) and limit > 0):
        raise InputError(f"expected a positive length, got {limit}", option="--limit")
    return float(limit)


def _direction_table(model: SerialModel, names: list[str], change: Array, std: Array
                     ) -> dict[str, dict[str, float]]:
    """``{name: {change, std, unit}}`` in the model file's units, for the directions
    today's poses see."""
    out = {}
    deg = model.angle_unit == "deg"
    angle = model.is_angle()
    for name, c, s in zip(names, change, std, strict=True):
        if not np.isfinite(c):
            continue
        is_angle = bool(angle[model.index([name])[0]])
        f = (180.0 / np.pi if deg else 1.0) if is_angle else 1.0
        out[name] = {"change": float(c * f), "std": float(s * f),
                     "unit": model.angle_unit if is_angle else model.length_unit}
    return out


def _poses(blocks: list, rows: Any, expected: Array, cal: Calibrated) -> list[dict]:
    """Per observation: its set, row, error, the error expected without a change."""
    from kinecal.registry.envelope import outside_calibrated_range

    out = []
    k = 0
    for b, r in zip(blocks, rows.block_r, strict=True):
        err = b.observation_errors(r)
        outside = outside_calibrated_range(cal, b)
        for i, e in enumerate(err):
            exp = float(np.sqrt(max(expected[k], 0.0)))
            entry = {"set": Path(b.source).name or b.source, "kind": b.kind, "row": i + 1,
                     "error": float(e), "expected": exp,
                     "ratio": float(e / exp) if exp > 0 else None}
            if outside is not None:
                entry["outside_calibrated_range"] = bool(outside[i])
            out.append(entry)
            k += 1
    return out
