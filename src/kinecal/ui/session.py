"""What the workbench holds: the model, the measurement files, the plan and the runs, each
read by the readers the command line uses, so that a bad file gets the command line's error
text (``kinecal: error: FILE, row N: ...``).

Files given on the command line are used where they are; a file dropped on the page is saved
first under the workbench's folder (``kinecal-ui/dropped/NAME``) and named by that path, as
the command line would name it when run from the same folder.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kinecal._files import write_bytes_atomic
from kinecal.errors import InputError

__all__ = ["DataSet", "Session", "error_text"]

Array = NDArray[np.float64]


def error_text(exc: InputError) -> str:
    """The command line's line for `exc` (``kinecal: error: ...``, `kinecal.cli.main`)."""
    return f"kinecal: error: {exc.one_line()}"


@dataclass
class DataSet:
    """A measurement file: its name in the page, the argument that reads it (a path or a
    bundled ``NAME:PART``), its kind and, for tracker files, the measurements."""

    name: str
    spec: str
    kind: str
    meas: object | None = None

    @property
    def n(self) -> int:
        return 0 if self.meas is None else len(self.meas.q)


@dataclass
class Session:
    """The workbench's state (module docstring); every change under `lock`."""

    workdir: Path
    base_link: str | None = None
    tip_links: list[str] = field(default_factory=list)
    model_spec: str | None = None
    model: object | None = None
    data: dict[str, DataSet] = field(default_factory=dict)
    plan: Array | None = None
    lock: threading.RLock = field(default_factory=threading.RLock)
    _urdf: dict = field(default_factory=dict)

    def urdf(self):
        """The model's URDF with its meshes when the model is a URDF file (read once)."""
        from kinecal.ui.scene import urdf_of

        spec = self.model_spec
        if spec not in self._urdf:
            self._urdf[spec] = urdf_of(spec)
        return self._urdf[spec]

    # ------------------------------------------------------------------ model
    @property
    def is_system(self) -> bool:
        from kinecal.kinematics.tree.system import is_system

        return self.model is not None and is_system(self.model)

    def set_model(self, spec: str) -> str:
        """Load MODEL `spec` (a bundled name, a model YAML, a system file or a URDF, with
        the session's base and tip links); the data sets of the previous model are
        dropped."""
        from kinecal.io.systems import load_machine

        model = load_machine(spec, base_link=self.base_link, tips=self.tip_links)
        with self.lock:
            self.model_spec, self.model = spec, model
            self.data.clear()
            self.plan = None
        return f"model {model.name}: {model.n_joints} joints, {model.n_params} parameters"

    def require_model(self):
        if self.model is None:
            raise InputError("no model yet: choose one in the Model box or drop a model "
                             "file (YAML or URDF) first")
        return self.model

    # ------------------------------------------------------------------ files
    def read_data(self, spec: str, name: str | None = None) -> DataSet:
        """Read a measurement file as ``kinecal calibrate MODEL SPEC`` would, and keep it."""
        from kinecal.datasets import bundled_csv
        from kinecal.io.kinds import kind_of_columns
        from kinecal.io.measurements import csv_header

        model = self.require_model()
        path = Path(spec)
        if not path.exists() and ":" in spec and not path.suffix:
            path = bundled_csv(spec)
        elif not path.is_file():
            raise InputError("file not found", file=spec, option="DATA")
        kind = kind_of_columns(csv_header(path), path)
        meas = None
        if self.is_system:
            from kinecal.io.system_data import read_system_data

            meas = read_system_data(path, model)
        elif kind == "tracker":
            from kinecal.io.measurements import read_measurements

            meas = read_measurements(path, model)
        if kind != "tracker":
            meas = None  # drawn: tracker rows only; the other kinds go to calibrate as files
        ds = DataSet(name or (spec if ":" in spec and not Path(spec).exists()
                              else Path(spec).name), spec, kind, meas)
        with self.lock:
            self.data[ds.name] = ds
        return ds

    def read_plan(self, spec: str) -> Array:
        """Joint values (rad) of a plan file ``q1..qn`` (what ``select-poses`` writes)."""
        from kinecal.io.measurements import read_joints

        q = read_joints(Path(spec), self.require_model())
        with self.lock:
            self.plan = q
        return q

    def save_dropped(self, name: str, content: bytes) -> Path:
        """Keep a dropped file under ``dropped/`` (a new name when taken); the path
        relative to the working folder when it is inside it."""
        folder = self.workdir / "dropped"
        folder.mkdir(parents=True, exist_ok=True)
        stem, suffix = os.path.splitext(Path(name).name or "dropped")
        path, k = folder / f"{stem}{suffix}", 1
        while path.exists():
            k += 1
            path = folder / f"{stem}-{k}{suffix}"
        write_bytes_atomic(path, content)
        try:
            return path.relative_to(Path.cwd())
        except ValueError:
            return path

    def load_file(self, spec: str) -> str:
        """Load any file the page accepts, by its suffix and columns: a model (``.yaml``,
        ``.yml``, ``.urdf``), a result (``.json``: shown in Run), measurements or a plan
        (``.csv``: joint columns alone make a plan). Returns what was loaded."""
        suffix = Path(spec).suffix.lower()
        if suffix in (".yaml", ".yml", ".urdf", ".xml"):
            return self.set_model(spec)
        if suffix != ".csv" and ":" in spec and not Path(spec).exists():
            ds = self.read_data(spec)
            return f"data {ds.name}: {ds.n} poses"
        if suffix == ".csv":
            from kinecal.io.measurements import csv_header

            model = self.require_model()
            header = csv_header(Path(spec))
            joints_only = bool(header) and not (set(header) - _joint_like(model))
            if joints_only:
                q = self.read_plan(spec)
                return f"plan {Path(spec).name}: {len(q)} poses"
            ds = self.read_data(spec)
            return f"data {ds.name}: {ds.kind}, {ds.n or 'its'} rows"
        raise InputError("expected a model (.yaml, .urdf), measurements or a plan (.csv) or "
                         "a result (.json)", file=spec)


def _joint_like(model) -> set[str]:
    """Column names a joints-only file may have: q1..qn, the joint names, a marker."""
    from kinecal.io.measurements import joint_names

    names = {f"q{i + 1}" for i in range(model.n_joints)} | {"marker"}
    try:
        names |= set(joint_names(model))
    except (InputError, AttributeError):
        names |= set(getattr(model, "joint_names", ()))
    return names
