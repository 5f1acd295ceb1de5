"""One batch job, run inside a worker process: load or simulate the data, calibrate.

`run_job` never raises for a job's own failure: it returns an outcome dict with the
error, so that one bad job cannot take the others down. The result dict is the
calibration JSON of DESIGN section 4 (`CalibrationResult.to_dict`) plus ``job`` (the job
specification, used to resume) and, for simulated jobs, ``truth`` (the true parameter
values in the model file's units, used by the coverage study).
"""

from __future__ import annotations

import time
import traceback
from typing import Any

import numpy as np

from kinecal.batch.jobs import Job
from kinecal.errors import InputError

__all__ = ["job_seeds", "run_job", "simulate_job"]


def job_seeds(seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent generators for a simulated job's calibration and validation poses.

    Seeding with ``[seed, k]`` gives streams that depend only on the job's seed, so a
    study with the same seeds and different methods or noise levels sees the same poses
    and the same true arm (common random numbers).
    """
    return np.random.default_rng([seed, 0]), np.random.default_rng([seed, 1])


def simulate_job(job: Job, model: Any) -> tuple[Any, Any, np.ndarray, list[str] | None]:
    """Simulated calibration data, validation data (or None), true parameters, free set.

    Parameters
    ----------
    job : Job
        A simulated job (``poses`` set).
    model : SerialModel
        Its nominal model.

    Returns
    -------
    data : Measurements
        ``job.poses`` noisy calibration poses.
    validate : Measurements or None
        ``job.validation_poses`` noisy poses of the same true arm.
    true_params : ndarray, shape (n_params,)
        True parameter vector (length unit, rad).
    free : list of str or None
        With ``errors: identifiable``, the parameters that carry the errors (identifiable
        from the poses at nominal, with `kinecal.calibrate`'s rank threshold); the
        calibration then identifies exactly these, so that each free parameter has a
        well-defined truth. None otherwise.
    """
    from kinecal.calibration.serial.api import CALIBRATION_RANK_TOL
    from kinecal.calibration.serial.problem import resolve_free
    from kinecal.calibration.serial.simulate import random_configurations, random_errors, simulate
    from kinecal.data import Measurements

    gen, gen_val = job_seeds(job.seed)
    names = None
    if job.errors == "identifiable":
        # errors only where the poses can see them, and exactly these identified: the
        # identified values then estimate the true values themselves (no confounded
        # parameter absorbs another's error, e.g. d2/d3 of parallel axes once beta2 != 0)
        q = random_configurations(model, job.poses, gen)
        probe = Measurements(q, np.zeros((len(q), 3)), None, "poses")
        names, _ = resolve_free(model, probe, "identifiable" if job.free == "all" else job.free,
                                tol=CALIBRATION_RANK_TOL)
        errors: Any = random_errors(model, gen, names)
        sim = simulate(model, job.poses, errors=errors, noise=job.noise, rng=gen, q=q)
    else:
        sim = simulate(model, job.poses, errors=job.errors, noise=job.noise, rng=gen)
    val = None
    if job.validation_poses:
        val = simulate(model, job.validation_poses, errors=sim.true_params - model.nominal,
                       noise=job.noise, rng=gen_val).data
    return sim.data, val, sim.true_params, names


def _truth_table(model: Any, true_params: np.ndarray) -> dict[str, float]:
    """True values in the model file's units (angles in deg when the file uses deg)."""
    scale = 180.0 / np.pi if model.angle_unit == "deg" else 1.0
    conv = np.where(model.is_angle(), scale, 1.0)
    return {n: float(v) for n, v in zip(model.parameter_names, true_params * conv, strict=True)}


def _calibrate_job(job: Job, model: Any, data: Any, val: Any, free: Any) -> Any:
    """The job's calibration, as ``kinecal calibrate`` runs it: `kinecal.calibrate`, or the
    joint-error calibration when the job (or the model file) asks for an error model."""
    from kinecal.calibration.serial.api import calibrate

    kw = dict(free=free, validate=val, rng=job.seed, loss=job.loss, maxiter=job.maxiter,
              target=job.target, options=job.options, sigma=job.sigma)
    if isinstance(data, list):  # several files: one problem (kinecal.calibration.blocks)
        if job.error_model is not None or job.harmonics is not None:
            raise InputError("error_model applies to one tracker file only, not to a list "
                             "of data files")
        return calibrate(model, data, job.method, **kw)
    if job.error_model is None and model.joint_errors is None and job.harmonics is None:
        return calibrate(model, data, job.method, **kw)
    from kinecal.calibration.serial.error_model import calibrate_error_model

    return calibrate_error_model(model, data, job.error_model or "model", method=job.method,
                                 harmonics=job.harmonics,
                                 **kw, **({} if job.folds is None else {"folds": job.folds}))


def _listed(spec: Any) -> list:
    """A job's file or files as a list (none: empty)."""
    return [] if spec is None else spec if isinstance(spec, list) else [spec]


def _tips(job: Job) -> list[str]:
    return [] if job.tip_link is None else [job.tip_link] if isinstance(job.tip_link, str) \
        else list(job.tip_link)


def _load(job: Job) -> Any:
    """The job's model: a serial chain, or a robot system (a system file, or a URDF with
    several tips; `kinecal.io.systems.load_machine`)."""
    from kinecal.io.systems import load_machine

    return load_machine(job.model, base_link=job.base_link, tips=_tips(job))


def _system_data(job: Job, system: Any) -> tuple[list, list | None]:
    """A robot system's data and validation files (their rows name their tips)."""
    from kinecal.io.system_data import read_system_data

    if job.simulated:
        raise InputError("a robot system's job takes data files (simulated jobs take one "
                         "chain)", option="model")
    if job.error_model is not None or job.harmonics is not None:
        raise InputError("error_model does not apply to a robot system", option="model")
    data = [read_system_data(f, system) for f in _listed(job.data)]
    val = [read_system_data(f, system) for f in _listed(job.validation)] or None
    return data, val


def run_job(job: Job) -> dict[str, Any]:
    """Run one job; return its outcome (never raises for the job's own errors).

    The job runs inside a silent collector of `kinecal.diagnostics`: its plausibility
    warnings (readers, simulation, calibration) are not issued as Python warnings on the
    worker's stderr, but returned, for the coordinating process to report once (numpy's
    floating-point warnings are off, as on the command line: kinecal checks its inputs
    and results itself).

    Returns
    -------
    dict
        ``{"name", "status": "done" | "failed", "seconds", "result": dict | None,
        "error": str, "kind": "" | "input" | "internal", "warnings": [{code, message}]}``;
        ``result`` is the calibration JSON with ``job`` (and ``truth`` for simulated jobs)
        added, its ``warnings`` the same as the outcome's.
    """
    from kinecal import diagnostics
    from kinecal.io.measurements import read_measurements

    t0 = time.perf_counter()
    found: list = []

    def outcome(status: str, result: Any = None, error: str = "", kind: str = "") -> dict:
        return {"name": job.name, "status": status, "seconds": time.perf_counter() - t0,
                "result": result, "error": error, "kind": kind,
                "warnings": [d.to_dict() for d in found]}

    try:
        # np.errstate, unlike warnings.catch_warnings, is safe in a thread pool's threads
        with diagnostics.collect() as found, np.errstate(all="ignore"):
            model = _load(job)
            truth, free = None, job.free
            if getattr(model, "convention", None) == "system":  # a robot system
                data, val = _system_data(job, model)
            elif job.simulated:
                data, val, truth, names = simulate_job(job, model)
                free = free if names is None else names
            elif isinstance(job.data, list) or isinstance(job.validation, list):
                from kinecal.io.kinds import read_kind  # several files of any kinds

                data = [read_kind(f, model) for f in _listed(job.data)]
                val = [read_kind(f, model) for f in _listed(job.validation)] or None
            else:
                data = read_measurements(job.data, model)
                val = (None if job.validation is None
                       else read_measurements(job.validation, model))
            res = _calibrate_job(job, model, data, val, free)
            res.warnings = list(found)  # the readers' warnings as well as the calibration's
            result = res.to_dict()
        result["job"] = job.spec()
        if truth is not None:
            result["truth"] = _truth_table(model, truth)
    except InputError as exc:
        return outcome("failed", error=exc.one_line(), kind="input")
    except Exception as exc:  # a job's failure must not stop the batch
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f" ({last.filename.rsplit('/', 1)[-1]}:{last.lineno})"
        return outcome("failed", error=f"{type(exc).__name__}: {exc}{where}", kind="internal")
    return outcome("done", result)
