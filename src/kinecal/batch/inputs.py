"""What a batch job reads and writes: path collisions refused, inputs fingerprinted.

`check_batch_paths` refuses, before any job runs, a batch whose result files would land
on one of its inputs (the jobs file, a model, a measurement file): ``--out .`` beside a
jobs file ``jobs.json`` with a job named ``jobs``, or a data file named ``summary.csv``.

`input_hash` fingerprints a job: its specification and the bytes of every file it reads.
The hash is stored with each result; a rerun resumes a job only when the hash is the same,
so a job whose measurement file or model was edited since is computed again.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from kinecal.errors import InputError

__all__ = ["SUMMARY_FILES", "check_batch_paths", "input_hash", "job_inputs"]

#: files a batch writes into its output directory besides ``<name>.json``
SUMMARY_FILES = ("summary.csv", "study.csv", "coverage.csv")


def job_inputs(job: Any) -> dict[str, Path]:
    """The files `job` reads (model, data, validation), resolved (bundled names too)."""
    from kinecal.io.bundled import input_file

    out = {}
    for key in ("model", "data", "validation"):
        spec = getattr(job, key, None)
        specs = spec if isinstance(spec, list) else [spec]
        for i, one in enumerate(specs):  # several data files: data, data 2, ...
            if one is not None and (path := input_file(one)) is not None:
                out[key if i == 0 else f"{key} {i + 1}"] = path
    return out


def _identity(path: Path) -> tuple[str, tuple[int, int] | None]:
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
    except OSError:
        return real, None
    return real, (st.st_dev, st.st_ino)


def check_batch_paths(jobs: Sequence[Any], out_dir: str | Path,
                      inputs: Iterable[str | Path] = ()) -> None:
    """Refuse a batch whose outputs would overwrite an input or each other.

    Parameters
    ----------
    jobs : sequence of Job
        The jobs (their names give the result files ``<out_dir>/<name>.json``).
    out_dir : str or Path
        The output directory (it may not exist yet).
    inputs : iterable of path
        Further files the batch must never write (the jobs file).

    Raises
    ------
    InputError
        `out_dir` is a file; a result or summary file is one of the inputs (under any
        name: links, relative paths) or an existing directory.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out} is a file, expected a directory", option="--out")
    protected: dict[object, str] = {}
    for path in inputs:
        real, ident = _identity(Path(path))
        protected[real] = "the jobs file"
        if ident is not None:
            protected[ident] = "the jobs file"
    for job in jobs:
        for key, path in job_inputs(job).items():
            real, ident = _identity(path)
            what = f"the {'validate' if key == 'validation' else key} file of job {job.name}"
            protected.setdefault(real, what)
            if ident is not None:
                protected.setdefault(ident, what)
    outputs = [(f"{job.name}.json", f"the result of job {job.name}") for job in jobs]
    outputs += [(name, f"the batch's {name}") for name in SUMMARY_FILES]
    for name, role in outputs:
        real, ident = _identity(out / name)
        if os.path.isdir(real):
            raise InputError(f"{out / name} is a directory; {role} cannot be written there",
                             option="--out")
        hit = protected.get(real) or (protected.get(ident) if ident is not None else None)
        if hit is not None:
            raise InputError(f"{out / name} would be {role} and is {hit}: refusing to "
                             "overwrite an input (choose another --out or rename the job)",
                             option="--out")


def _file_digest(path: Path, cache: dict) -> str:
    try:
        st = path.stat()
    except OSError:
        return "missing"
    key = (os.path.realpath(path), st.st_size, st.st_mtime_ns)
    if key not in cache:
        h = hashlib.sha256()
        try:
            with open(path, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    h.update(block)
        except OSError:
            return "unreadable"
        cache[key] = h.hexdigest()
    return cache[key]


def input_hash(job: Any, cache: dict | None = None) -> str:
    """SHA-256 of the job's specification and of the bytes of every file it reads.

    `cache` (a dict kept across calls) avoids hashing a file shared by many jobs again
    while its size and modification time stay the same.
    """
    cache = {} if cache is None else cache
    h = hashlib.sha256(json.dumps(job.spec(), sort_keys=True, default=str).encode())
    for key, path in sorted(job_inputs(job).items()):
        h.update(f"\0{key}\0{_file_digest(path, cache)}".encode())
    return h.hexdigest()
