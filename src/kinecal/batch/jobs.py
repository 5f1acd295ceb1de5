"""The jobs file of ``kinecal batch``: a list of jobs and/or study grids (pydantic schema).

A jobs file is YAML (or JSON)::

    jobs:
      - {name: arm-0001, model: irb120, data: arm-0001.csv, validate: arm-0001-val.csv}
    study:
      {model: irb120, methods: [lm, hybrid-ga], seeds: [0, 1, 2], noise: [0.01, 0.02],
       poses: [30], validation_poses: 100}

Each entry of ``jobs`` is one calibration of measured data (``data``) or of simulated
data (``poses`` instead of ``data``). A ``study`` (one mapping or a list of them) expands
into the full grid ``methods x noise x poses x seeds`` of simulated jobs named
``<name>-<method>-n<noise>-p<poses>-s<seed>``. Relative paths are relative to the jobs
file's directory.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from kinecal._files import read_text
from kinecal._limits import MAX_JOBS, check_count
from kinecal._yaml import load_yaml
from kinecal.batch.job_checks import JOB_BYTES, check_job, check_models
from kinecal.errors import InputError

__all__ = ["Job", "JobsFile", "Study", "expand_study", "load_jobs", "parse_jobs"]

_NAME = r"^[A-Za-z0-9_][A-Za-z0-9_.+-]*$"

#: keys recorded in a job's specification only when given (see `Job.spec`)
OPTIONAL_KEYS = ("error_model", "harmonics", "folds", "sigma", "base_link", "tip_link",
                 "serial")

#: how the true geometry of a simulated job deviates from nominal
ErrorsMode = Literal["random", "zero", "identifiable"]


def _check_method(method: str) -> str:
    from kinecal.calibration.serial.api import CALIBRATION_METHODS

    if method not in CALIBRATION_METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of "
                         f"{', '.join(CALIBRATION_METHODS)}")
    return method


def _positive_sigma(value: Any) -> Any:
    """``sigma``: a positive number, or a list of them (None for a file whose noise is
    estimated), one per data file."""
    values = value if isinstance(value, list) else [value]
    for v in values:
        if v is not None and not (isinstance(v, int | float) and not isinstance(v, bool)
                                  and math.isfinite(v) and v > 0):
            raise ValueError(f"expected a positive finite number, got {v!r}")
    if isinstance(value, list) and not value:
        raise ValueError("expected one value per data file")
    return value


class _Common(BaseModel):
    """Settings shared by jobs and studies (see `Job`)."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True)

    model: str = Field(min_length=1)
    validation_poses: int = Field(0, ge=0)
    errors: ErrorsMode = "random"
    free: str | list[str] = "identifiable"
    loss: str = "linear"
    maxiter: int | None = Field(None, ge=1)
    target: float | None = Field(None, ge=0, allow_inf_nan=False)
    options: dict[str, Any] | None = None
    error_model: str | None = Field(None, min_length=1)
    harmonics: int | None = Field(None, ge=1)
    folds: int | None = Field(None, ge=2)
    sigma: float | list[float | None] | None = None

    _sigma = field_validator("sigma")(_positive_sigma)
    base_link: str | None = Field(None, min_length=1)
    tip_link: str | list[str] | None = Field(None, min_length=1)




class Job(_Common):
    """One calibration.

    Attributes
    ----------
    name : str
        Unique job name; the result is ``DIR/<name>.json`` (letters, digits, ``_.+-``).
    model : str
        Bundled model name or model YAML path.
    data : str or list of str, optional
        Measurement CSV (path or bundled ``NAME:PART``), or several files of any
        measurement kinds calibrated as one problem (docs/measurement-kinds.md). Without
        it the job is simulated.
    validation : str or list of str, optional
        Validation CSV(s) of any kind (key ``validate`` in the file), only with ``data``.
    poses : int, optional
        Number of simulated calibration poses (instead of ``data``).
    validation_poses : int
        Number of simulated validation poses (same true arm, same noise).
    noise : float
        Standard deviation of the simulated noise per coordinate (model length unit).
    errors : {"random", "zero", "identifiable"}
        True deviations of a simulated arm: uniform within the model's tolerances on every
        calibratable parameter, none, or only on the parameters identifiable from the poses
        at nominal, which are then exactly the free parameters of the calibration (so that
        the identified values estimate the truth itself: the Monte Carlo coverage study
        of the standard errors).
    seed : int
        Seed of the simulation and of the calibration's randomness.
    method, free, loss, maxiter, target, options
        Passed to `kinecal.calibrate`.
    error_model, harmonics, folds
        Non-geometric joint errors, as ``kinecal calibrate --error-model``, ``--harmonics``,
        ``--folds`` (`kinecal.calibration.serial.error_model.calibrate_error_model`).
    sigma : float or list, optional
        The instrument's stated noise per coordinate (``--sigma``): the residual is tested
        against it (`kinecal.calibration.diagnostics.noise`); with several data files one
        value per file (null: estimated).
    base_link, tip_link : str, optional
        (``tip_link`` may list several tips: a robot system of a URDF tree,
        docs/systems.md)
        URDF models: the chain's first and last link (``--base-link``, ``--tip-link``).
    serial : str, optional
        The robot's serial number in the registry (``kinecal batch --db``; default the
        job's name).
    """

    name: str = Field(pattern=_NAME, max_length=200)
    serial: str | None = Field(None, min_length=1, max_length=200)
    data: str | list[str] | None = None
    validation: str | list[str] | None = Field(None, alias="validate")
    poses: int | None = Field(None, ge=1)
    noise: float = Field(0.0, ge=0, allow_inf_nan=False)
    seed: int = Field(0, ge=0)
    method: str = "lm"

    _method = field_validator("method")(_check_method)

    @model_validator(mode="after")
    def _source(self) -> Job:
        if (self.data is None) == (self.poses is None):
            raise ValueError("expected either 'data' (a measurement CSV) or 'poses' "
                             "(simulated), not both or neither")
        if self.data is not None and (self.validation_poses or self.noise):
            raise ValueError("'validation_poses' and 'noise' apply to simulated jobs only")
        if self.data is None and self.validation is not None:
            raise ValueError("'validate' applies to jobs with 'data' only; use "
                             "'validation_poses' for simulated jobs")
        return self

    @property
    def simulated(self) -> bool:
        """True when the job simulates its data."""
        return self.data is None

    def spec(self) -> dict[str, Any]:
        """The job as a plain dict (file keys), recorded in its result for resuming.

        The keys added after the first release (`OPTIONAL_KEYS`) appear only when given,
        so that results written before them still resume.
        """
        out = self.model_dump(by_alias=True, mode="json")
        return {k: v for k, v in out.items() if not (k in OPTIONAL_KEYS and v is None)}


class Study(_Common):
    """A grid of simulated jobs: ``methods x noise x poses x seeds``.

    ``seeds`` is a list or a count ``n`` (seeds ``0 .. n-1``); ``name`` prefixes the job
    names (default: the model name).
    """

    name: str | None = Field(None, pattern=_NAME, max_length=100)
    methods: list[str] = Field(default_factory=lambda: ["lm"], min_length=1)
    seeds: list[int] | int = Field(default_factory=lambda: [0])
    noise: list[float] = Field(default_factory=lambda: [0.0], min_length=1)
    poses: list[int] = Field(min_length=1)

    @field_validator("methods")
    @classmethod
    def _methods(cls, value: list[str]) -> list[str]:
        return [_check_method(m) for m in value]

    @field_validator("seeds")
    @classmethod
    def _seeds(cls, value: list[int] | int) -> list[int] | int:
        # a count stays a count: expand_study makes the seeds once the grid's size is checked
        if (value < 1) if isinstance(value, int) else (not value or min(value) < 0):
            raise ValueError("expected a positive count or a list of seeds >= 0")
        return value

    def size(self) -> int:
        """Number of jobs of the grid."""
        seeds = self.seeds if isinstance(self.seeds, int) else len(self.seeds)
        return len(self.methods) * len(self.noise) * len(self.poses) * seeds

    @field_validator("noise")
    @classmethod
    def _noise(cls, value: list[float]) -> list[float]:
        if not all(math.isfinite(v) and v >= 0 for v in value):
            raise ValueError("expected finite noise standard deviations >= 0")
        return value

    @field_validator("poses")
    @classmethod
    def _poses(cls, value: list[int]) -> list[int]:
        if min(value) < 1:
            raise ValueError("expected positive pose counts")
        return value


class JobsFile(BaseModel):
    """Top level of a jobs file: ``jobs`` and/or ``study`` (one or a list)."""

    model_config = ConfigDict(extra="forbid")

    jobs: list[Job] = Field(default_factory=list)
    study: Study | list[Study] | None = None


def expand_study(study: Study) -> list[Job]:
    """The jobs of a study grid, in the order methods, noise, poses, seeds."""
    prefix = study.name or Path(study.model).stem
    shared = study.model_dump(exclude={"name", "methods", "seeds", "noise", "poses"})
    seeds = study.seeds if isinstance(study.seeds, list) else list(range(study.seeds))
    jobs = []
    for method, noise, poses, seed in itertools.product(study.methods, study.noise,
                                                        study.poses, seeds):
        name = f"{prefix}-{method}-n{noise:g}-p{poses}-s{seed}"
        jobs.append(Job(name=name, method=method, noise=noise, poses=poses, seed=seed,
                        **shared))
    return jobs


def _resolve(spec: str | list[str] | None, base: Path, bundled: bool) -> Any:
    """Make a relative path absolute against `base`; keep bundled names as they are."""
    if spec is None:
        return None
    if isinstance(spec, list):
        return [_resolve(s, base, bundled) for s in spec]
    path = Path(spec).expanduser()
    if path.is_absolute():
        return str(path)
    candidate = base / path
    if candidate.exists() or (path.suffix and not bundled):
        return str(candidate.resolve())
    if bundled and path.suffix.lower() in (".yaml", ".yml", ".urdf"):
        return str(candidate.resolve())
    return spec  # bundled model name or NAME:PART dataset


def _first_error(exc: ValidationError) -> str:
    err = exc.errors()[0]
    where = ".".join(str(p) for p in err["loc"]) or "top level"
    return f"{where}: {err['msg']}"


def parse_jobs(doc: Any, base: str | Path = ".", source: str | Path | None = None) -> list[Job]:
    """Validate a parsed jobs document and return its jobs (study grids expanded).

    Parameters
    ----------
    doc : dict
        The parsed YAML/JSON mapping.
    base : str or Path
        Directory that relative paths are relative to.
    source : str or Path, optional
        File name used in error messages.

    Raises
    ------
    InputError
        Schema violation, no job at all, or a job name used twice.
    """
    if not isinstance(doc, dict):
        raise InputError("expected a mapping with 'jobs' and/or 'study'", file=source)
    try:
        parsed = JobsFile.model_validate(doc)
    except ValidationError as exc:
        raise InputError(_first_error(exc), file=source) from None
    base = Path(base)
    jobs = [j.model_copy(update={"model": _resolve(j.model, base, True),
                                 "data": _resolve(j.data, base, False),
                                 "validation": _resolve(j.validation, base, False)})
            for j in parsed.jobs]
    studies = parsed.study if isinstance(parsed.study, list) else [parsed.study]
    total = len(jobs) + sum(s.size() for s in studies if s is not None)
    try:  # before expanding: a billion seeds ran out of memory
        check_count(total, "seeds" if parsed.study is not None else "jobs",
                    bytes_per_item=JOB_BYTES, what="jobs", minimum=0, most=MAX_JOBS)
    except InputError as exc:
        raise InputError(f"{exc.option}: {exc.message}", file=source) from None
    for study in studies:
        if study is not None:
            study = study.model_copy(update={"model": _resolve(study.model, base, True)})
            jobs.extend(expand_study(study))
    if not jobs:
        raise InputError("no jobs: expected a non-empty 'jobs' list or a 'study'", file=source)
    seen: dict[str, str] = {}
    for job in jobs:
        key = job.name.casefold()
        if key in seen:
            twice = ("is used twice" if seen[key] == job.name else
                     f"and {seen[key]!r} differ only in case (their result files collide on "
                     "macOS and Windows)")
            raise InputError(f"job name {job.name!r} {twice}", file=source)
        seen[key] = job.name
        check_job(job, source)
    check_models(jobs, source)
    return jobs


def load_jobs(path: str | Path) -> list[Job]:
    """Read a jobs file (YAML or JSON) and return its jobs; see `parse_jobs`."""
    path = Path(path)
    doc = load_yaml(read_text(path), path)
    return parse_jobs(doc, path.parent, path)
