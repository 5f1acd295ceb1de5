"""Checks of a parsed job before any runs: the method's options, the error model, the input
files, pose counts within memory, and what needs the model itself (URDF links, noise and
stated sigma against the machine's size). Each failure names the job and its key.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from kinecal._limits import check_count
from kinecal.errors import InputError

__all__ = ["JOB_BYTES", "JOB_POSE_BYTES", "check_job", "check_models"]


#: memory of one job, parsed and checked (measured 4.3 kB), with a margin
JOB_BYTES = 16384
#: peak memory of a simulated job per pose (calibration and validation): measured 1.3 kB
#: (irb120, lm), with a margin
JOB_POSE_BYTES = 4096


class Job(Protocol):
    """What the checks read of a job (`kinecal.batch.jobs.Job` has it; this module does not
    import that one, which imports these checks)."""

    name: str
    model: str
    method: str
    data: Any
    poses: int | None
    validation_poses: int
    noise: float
    loss: str
    maxiter: int | None
    target: float | None
    options: dict[str, Any] | None
    error_model: str | None
    harmonics: int | None
    folds: int | None
    sigma: Any
    base_link: str | None
    tip_link: str | None


def check_job(job: Job, source: str | Path | None) -> None:
    """Options the job's method would ignore, and pose counts beyond the memory."""
    from kinecal._files import check_input_file
    from kinecal.calibration.method_options import check_method_options

    for key in ("data", "validation"):
        value = getattr(job, key)
        for spec in [] if value is None else value if isinstance(value, list) else [value]:
            try:
                check_input_file(spec, "a CSV file")
            except InputError as exc:
                raise InputError(f"job {job.name}: {exc.one_line()}", file=source) from None
    files = job.data if isinstance(job.data, list) else [job.data]
    if isinstance(job.sigma, list) and len(job.sigma) != len(files):
        raise InputError(f"job {job.name}: sigma: {len(job.sigma)} values for "
                         f"{len(files)} data files", file=source)
    try:
        check_method_options(job.method, loss=job.loss, maxiter=job.maxiter,
                             target=job.target, options=job.options,
                             names={k: k for k in ("loss", "maxiter", "target", "options")})
        _check_error_model(job)
        if (job.base_link is not None or job.tip_link is not None) and not _is_urdf(job.model) \
                and not _is_system(job.model):
            raise InputError("base_link and tip_link apply to URDF models only, not "
                             f"to {job.model!r}", option="base_link")
        if job.poses is not None:
            check_count(job.poses + job.validation_poses, "poses",
                        bytes_per_item=JOB_POSE_BYTES)
    except InputError as exc:
        raise InputError(f"job {job.name}: {_key(exc.option)}: {exc.message}",
                         file=source) from None


def _key(option: str | None) -> str:
    """The jobs-file key of an option named as on the command line (``--error-model`` ->
    ``error_model``)."""
    if option is None:
        return "job"
    return option[2:].replace("-", "_") if option.startswith("--") else option


def _is_system(model: str) -> bool:
    from kinecal.io.systems import is_system_file

    return is_system_file(model)


def _is_urdf(model: str) -> bool:
    from kinecal.io.models import is_urdf_path

    return is_urdf_path(model)


def _check_error_model(job: Job) -> None:
    """The error-model keys as ``kinecal calibrate`` checks ``--error-model``, ``--harmonics``
    and ``--folds``: known families, options the choice uses, a least-squares method."""
    from kinecal.calibration.method_options import check_error_model_options
    from kinecal.calibration.serial.error_model_spec import (
        LSQ_METHODS,
        MAX_HARMONICS,
        parse_error_model,
    )

    if job.error_model is not None:
        families = parse_error_model(job.error_model)
        if families != () and job.method not in LSQ_METHODS:
            raise InputError(f"error model {job.error_model} needs a least-squares method "
                             f"({', '.join(LSQ_METHODS)}), got method {job.method}",
                             option="error_model")
    check_error_model_options(job.error_model, harmonics=job.harmonics, folds=job.folds)
    if job.harmonics is not None and job.harmonics > MAX_HARMONICS:
        raise InputError(f"expected a harmonic order 1..{MAX_HARMONICS}, got {job.harmonics}",
                         option="harmonics")


def check_models(jobs: list[Job], source: str | Path | None) -> None:
    """What needs the model itself, once per distinct (model, base_link, tip_link):

    * the chain of a URDF model with ``base_link`` / ``tip_link`` (as the command line
      loads it: unknown links are refused);
    * simulated ``noise`` and a stated ``sigma`` not larger than the machine
      (`kinecal.calibration.diagnostics.sizes`).

    A model that cannot be loaded otherwise is left to its jobs, which record the error.
    """
    from kinecal.calibration.diagnostics.sizes import check_length_noise, serial_size
    from kinecal.io.systems import load_machine

    loaded: dict[tuple, Any] = {}
    for job in jobs:
        links = job.base_link is not None or job.tip_link is not None
        if not (links or job.noise > 0 or job.sigma is not None):
            continue
        tips = [] if job.tip_link is None else [job.tip_link] if isinstance(
            job.tip_link, str) else list(job.tip_link)
        key = (job.model, job.base_link, tuple(tips))
        try:
            if key not in loaded:
                try:
                    loaded[key] = load_machine(job.model, base_link=job.base_link, tips=tips)
                except InputError:
                    if links:
                        raise
                    loaded[key] = None
            model = loaded[key]
            if model is None:
                continue
            size = serial_size(model)
            check_length_noise(job.noise, size, "noise", model.length_unit)
            for sigma in job.sigma if isinstance(job.sigma, list) else [job.sigma]:
                check_length_noise(sigma, size, "sigma", model.length_unit, "stated noise")
        except InputError as exc:
            text = (f"{_key(exc.option)}: {' '.join(exc.message.split())}"
                    if exc.option is not None else f"model: {exc.one_line()}")
            raise InputError(f"job {job.name}: {text}", file=source) from None
