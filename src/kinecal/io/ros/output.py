"""Files of a bag import: a measurement CSV, or a folder for hand-eye from images.

`write_rows`: ``q1..qn`` (the model's angle unit) and ``x, y, z`` (its length unit), with
``qw, qx, qy, qz`` for poses: kinecal's measurement format. `write_folder`: one image per
kept dwell, ``camera.yaml``, ``stations.csv`` (``image, q1..qn``), ``robot_poses.csv``
(``image`` and the flange pose ``flange_x .. flange_qz`` that ``kinecal handeye-images``
reads: from ``--tf`` / ``--poses`` when given, else the model's flange, D-H frame n in the
robot base, without the model file's base and tool) and ``measurements.csv`` with
``--points`` / ``--poses`` / ``--tf``. The folder is built beside its destination
(``.NAME.kinecal-import-PID``) and moved into place when complete: nothing half-written.
A run that finds such a folder of a process no longer running (one killed mid-way) removes
it; a run that finds the destination filled by another meanwhile leaves it alone and fails.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
from pathlib import Path

import numpy as np

from kinecal.errors import InputError
from kinecal.io.csvtable import write_table
from kinecal.io.ros.images import ImageWriter
from kinecal.io.ros.importer import BagImport, ImportOptions, import_bag
from kinecal.kinematics.serial.model import SerialModel
from kinecal.spatial import invert_transform, pq_from_transform

__all__ = ["clean_stale", "flange_poses", "write_folder", "write_rows"]

_QUAT = ("qw", "qx", "qy", "qz")


def _check_kept(res: BagImport, path) -> None:
    if not res.kept:
        reasons = "; ".join(f"dwell {k + 1}: {why}" for k, why in res.dropped[:3])
        raise InputError(f"none of the {len(res.dwells)} dwells could be kept ({reasons}"
                         f"{'; ...' if len(res.dropped) > 3 else ''}): nothing written",
                         file=path)


def _columns(res: BagImport, model: SerialModel) -> dict:
    q = res.q / model.joint_scale()
    cols = {f"q{i + 1}": q[:, i] for i in range(model.n_joints)}
    if res.xyz is not None:
        cols.update({c: res.xyz[:, k] for k, c in enumerate("xyz")})
    elif res.poses is not None:
        pq = pq_from_transform(res.poses)
        cols.update({c: pq[:, k] for k, c in enumerate(("x", "y", "z", *_QUAT))})
    return cols


def write_rows(path: str | Path, res: BagImport, model: SerialModel,
               bag: str | Path | None = None) -> None:
    """Write the kept rows as a measurement CSV (module docstring); `InputError` naming
    `bag` (the file imported, else `path`) when no dwell was kept."""
    _check_kept(res, path if bag is None else bag)
    write_table(path, _columns(res, model))


def flange_poses(res: BagImport, model: SerialModel) -> np.ndarray:
    """``(K, 4, 4)`` flange poses of the rows: the imported poses, else the model's flange
    (base and tool of the model file left out)."""
    if res.poses is not None:
        return res.poses
    from kinecal.kinematics.serial.frames import frame_transform

    p = model.nominal
    for k, name in enumerate(model.parameter_names):
        if name.startswith(("base.", "tool.")):
            p[k] = 0.0
    T = model.fk(res.q, p)  # the nominal orientations of the base and tool frames remain
    T = invert_transform(frame_transform(model, p, "base")) @ T
    if "tool.rx" in model.parameter_names:
        T = T @ invert_transform(frame_transform(model, p, "tool"))
    return T


_TMP = ".{name}.kinecal-import-"


def _alive(pid: int) -> bool:
    """True when a process `pid` runs (or may: one of another user)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True
    return True


def clean_stale(out: Path) -> list[Path]:
    """Remove the build folders of `out` left by processes that no longer run (killed
    mid-way); the folders removed."""
    prefix = _TMP.format(name=out.name)
    pattern = re.compile(re.escape(prefix) + r"(\d+)$")
    gone = []
    try:
        siblings = list(out.parent.iterdir())
    except OSError:
        return gone
    for p in siblings:
        m = pattern.match(p.name)
        if m and p.is_dir() and not p.is_symlink() and int(m.group(1)) != os.getpid() \
                and not _alive(int(m.group(1))):
            shutil.rmtree(p, ignore_errors=True)
            gone.append(p)
    return gone


def _move_into_place(tmp: Path, out: Path) -> None:
    """Rename the finished folder `tmp` to `out` (new, or an empty folder); another run
    that filled `out` meanwhile wins, this one fails with nothing changed."""
    try:
        if out.is_dir() and not out.is_symlink() and not any(out.iterdir()):
            out.rmdir()
        os.rename(tmp, out)
    except OSError as exc:
        if exc.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
            raise InputError(f"{out} was filled by another run while this one worked: "
                             "nothing written", option="--out") from None
        raise


def write_folder(bag: str | Path, model: SerialModel, opts: ImportOptions,
                 out: str | Path) -> BagImport:
    """Import `bag` with images into the folder `out` (new or empty; module docstring)."""
    out = Path(out)
    clean_stale(out)
    tmp = out.parent / (_TMP.format(name=out.name) + str(os.getpid()))
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        writer = ImageWriter(tmp, opts.images, opts.camera_info)
        res = import_bag(bag, model, opts, writer)
        _check_kept(res, bag)
        names = np.array(res.images, dtype=str)
        cols = _columns(res, model)
        write_table(tmp / "stations.csv",
                    {"image": names, **{k: v for k, v in cols.items() if k.startswith("q")}})
        pq = pq_from_transform(flange_poses(res, model))
        write_table(tmp / "robot_poses.csv",
                    {"image": names, **{f"flange_{c}": pq[:, k] for k, c in
                                        enumerate(("x", "y", "z", *_QUAT))}})
        if res.xyz is not None or res.poses is not None:
            write_table(tmp / "measurements.csv", cols)
        kept = set(res.images)
        for f in tmp.iterdir():  # images of dropped dwells
            if f.name.startswith("dwell_") and f.name not in kept:
                f.unlink()
        _move_into_place(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return res
