"""Hand-eye pose pairs: CSV and OpenCV FileStorage YAML readers and writers.

CSV (DESIGN sec. 4): one row per station, columns ``flange_x, flange_y, flange_z,
flange_qw, flange_qx, flange_qy, flange_qz`` (``flange2base``) and the same seven with
prefix ``target_`` (``target2cam``); quaternions (w, x, y, z), lengths in one unit.

YAML: OpenCV FileStorage as written by ``cv::FileStorage`` (``%YAML:1.0``, matrices as
``!!opencv-matrix`` with ``rows, cols, dt, data``) holding ``frameCount`` and 4x4
matrices ``T1_i`` (``flange2base``) and ``T2_i`` (``target2cam``), i = 0 .. frameCount-1,
the layout of the handeye_calib_camodocal recordings (see docs/handeye.md for how the
frame conventions of that recording were established).

Every write is atomic; every bad input raises `InputError` naming the file and the row
(CSV: 1-based data row; YAML: the station index i of ``T1_i``/``T2_i``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray

from kinecal._files import read_text, write_text_atomic
from kinecal.errors import InputError
from kinecal.io.csvtable import read_table, write_table
from kinecal.spatial import check_rotation, pq_from_transform, transform_from_pq

Array = NDArray[np.float64]

__all__ = [
    "FLANGE_COLUMNS",
    "TARGET_COLUMNS",
    "pose_columns",
    "read_handeye_csv",
    "read_handeye_pairs",
    "read_handeye_yaml",
    "write_handeye_csv",
    "write_handeye_yaml",
]

_PQ = ("x", "y", "z", "qw", "qx", "qy", "qz")


def pose_columns(prefix: str) -> list[str]:
    """Column names ``prefix_x .. prefix_qz`` of a pose (x, y, z, qw, qx, qy, qz)."""
    return [f"{prefix}_{c}" for c in _PQ]


FLANGE_COLUMNS = pose_columns("flange")
TARGET_COLUMNS = pose_columns("target")


def read_handeye_pairs(path: str | Path) -> tuple[Array, Array]:
    """Read pose pairs from ``.csv`` or ``.yml``/``.yaml`` (OpenCV FileStorage).

    Returns
    -------
    flange2base, target2cam : ndarray, shape (n, 4, 4)
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return read_handeye_csv(path)
    if suffix in (".yml", ".yaml"):
        return read_handeye_yaml(path)
    raise InputError(f"unknown file type {suffix or '(none)'!r}; expected .csv, .yml or .yaml",
                     file=path)


def _poses_from_columns(cols: dict[str, Array], prefix: str, path: Path) -> Array:
    pq = np.column_stack([cols[c] for c in pose_columns(prefix)])
    norm = np.linalg.norm(pq[:, 3:], axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > 1e-3)
    if bad.size:
        r = int(bad[0])
        raise InputError(
            f"{prefix} quaternion has norm {norm[r]:.6f}, expected a unit quaternion "
            "(qw, qx, qy, qz)",
            file=path,
            row=r + 1,
        )
    return transform_from_pq(pq)


def read_handeye_csv(path: str | Path) -> tuple[Array, Array]:
    """Read the hand-eye CSV (columns `FLANGE_COLUMNS` and `TARGET_COLUMNS`).

    Returns
    -------
    flange2base, target2cam : ndarray, shape (n, 4, 4)
        Lengths in the file's unit.
    """
    path = Path(path)
    cols = read_table(path, FLANGE_COLUMNS + TARGET_COLUMNS, min_rows=3)
    return _poses_from_columns(cols, "flange", path), _poses_from_columns(cols, "target", path)


def write_handeye_csv(path: str | Path, flange2base: Array, target2cam: Array) -> None:
    """Write pose pairs ``(n, 4, 4)`` as the hand-eye CSV (atomic)."""
    cols = {}
    for prefix, T in (("flange", flange2base), ("target", target2cam)):
        pq = pq_from_transform(np.asarray(T, dtype=float))
        cols.update({name: pq[:, k] for k, name in enumerate(pose_columns(prefix))})
    write_table(path, cols)


class _OpenCVLoader(yaml.SafeLoader):
    """Safe loader that accepts OpenCV's ``!!opencv-matrix`` tags."""


def _opencv_matrix(loader: yaml.SafeLoader, node: yaml.Node) -> dict:
    return loader.construct_mapping(node, deep=True)


_OpenCVLoader.add_constructor("tag:yaml.org,2002:opencv-matrix", _opencv_matrix)


def _matrix(doc: dict, key: str, path: Path, station: int) -> Array:
    # The key (T1_<station>) locates the error in a FileStorage file: no row number.
    node = doc.get(key)
    if node is None:
        raise InputError(f"missing matrix {key}", file=path)
    try:
        rows, cols = int(node["rows"]), int(node["cols"])
        data = np.asarray(node["data"], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{key}: expected an opencv-matrix with rows, cols and data",
                         file=path) from None
    if (rows, cols) != (4, 4) or data.size != 16:
        raise InputError(f"{key}: {rows}x{cols} matrix with {data.size} values, expected 4x4",
                         file=path)
    T = data.reshape(4, 4)
    if not np.isfinite(T).all():
        raise InputError(f"{key}: contains NaN or infinite values", file=path)
    if np.abs(T[3] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-6:
        raise InputError(f"{key}: last row must be (0, 0, 0, 1)", file=path)
    try:
        check_rotation(T[:3, :3], tol=1e-4, name=key)
    except InputError as exc:
        raise InputError(exc.message, file=path) from None
    return T


def read_handeye_yaml(path: str | Path) -> tuple[Array, Array]:
    """Read an OpenCV FileStorage YAML with ``frameCount``, ``T1_i`` and ``T2_i``.

    Returns
    -------
    flange2base, target2cam : ndarray, shape (n, 4, 4)
        ``T1_i`` and ``T2_i`` as stored (lengths in the file's unit).
    """
    path = Path(path)
    lines = read_text(path).splitlines()
    if lines and lines[0].startswith("%YAML:"):  # OpenCV's non-standard directive
        lines = lines[1:]
    try:
        doc = yaml.load("\n".join(lines), Loader=_OpenCVLoader)
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML: {' '.join(str(exc).split())}", file=path) from None
    if not isinstance(doc, dict):
        raise InputError("expected a mapping with frameCount, T1_i and T2_i", file=path)
    try:
        n = int(doc["frameCount"])
    except (KeyError, TypeError, ValueError):
        n = sum(1 for k in doc if str(k).startswith("T1_"))
    if n < 3:
        raise InputError(f"{n} stations, expected at least 3 (T1_i/T2_i pairs)", file=path)
    F = np.stack([_matrix(doc, f"T1_{i}", path, i) for i in range(n)])
    C = np.stack([_matrix(doc, f"T2_{i}", path, i) for i in range(n)])
    return F, C


def _fs_matrix(name: str, T: Array) -> str:
    vals = ", ".join(repr(float(v)) for v in np.asarray(T, dtype=float).ravel())
    return f"{name}: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ {vals} ]\n"


def write_handeye_yaml(path: str | Path, flange2base: Array, target2cam: Array) -> None:
    """Write pose pairs ``(n, 4, 4)`` as OpenCV FileStorage YAML (``T1_i``, ``T2_i``), atomic."""
    F = np.asarray(flange2base, dtype=float)
    C = np.asarray(target2cam, dtype=float)
    parts = ["%YAML:1.0\n", f"frameCount: {len(F)}\n"]
    for i in range(len(F)):
        parts.append(_fs_matrix(f"T1_{i}", F[i]))
        parts.append(_fs_matrix(f"T2_{i}", C[i]))
    write_text_atomic(path, "".join(parts))
