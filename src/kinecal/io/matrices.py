"""4x4 transform matrices in files: their check (last row ``0 0 0 1``, orthonormal
rotation) and OpenCV FileStorage YAML (``%YAML:1.0``, ``!!opencv-matrix`` with ``rows, cols,
dt, data``) entries and lists of them, as ``cv::FileStorage`` writes a ``cv::Mat`` or a
``std::vector<cv::Mat>``. Used by the pose tables (`kinecal.io.poses`) and the hand-eye
files (`kinecal.io.handeye`, which re-exports `read_matrix_lists`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray

from kinecal._files import read_text
from kinecal._yaml import load_yaml
from kinecal.errors import InputError
from kinecal.spatial import check_rotation

Array = NDArray[np.float64]

__all__ = ["check_matrices", "load_filestorage", "matrix_entry", "matrix_node", "matrix_yaml",
           "read_matrix_lists"]


def check_matrices(M: Array, what: str, path: Path, rows: list | None = None) -> None:
    """Refuse 4x4 matrices whose last row is not ``0 0 0 1`` or whose rotation part is not
    orthonormal (`InputError` naming the data row, or the entry of `rows`)."""
    for k, T in enumerate(M):
        where = {"row": k + 1} if rows is None else {}
        label = f"{what}" if rows is None else f"{what} {rows[k]}"
        if np.abs(T[3] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-6:
            raise InputError(f"{label}: last row {T[3].tolist()}, expected 0 0 0 1",
                             file=path, **where)
        try:
            check_rotation(T[:3, :3], tol=1e-4, name=label)
        except InputError as exc:
            raise InputError(exc.message, file=path, **where) from None


class _OpenCVLoader(yaml.SafeLoader):
    """Safe loader that accepts OpenCV's ``!!opencv-matrix`` tags."""


def _opencv_matrix(loader: yaml.SafeLoader, node: yaml.Node) -> dict:
    return loader.construct_mapping(node, deep=True)


_OpenCVLoader.add_constructor("tag:yaml.org,2002:opencv-matrix", _opencv_matrix)


def matrix_node(node, key: str, path: Path) -> Array:
    """A checked 4x4 transform from an ``!!opencv-matrix`` node; `key` (``T1_<station>``,
    ``base2gripper[3]``) locates an error in the file."""
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
    check_matrices(T[None], key, path, rows=[""])
    return T


def matrix_entry(doc: dict, key: str, path: Path) -> Array:
    """The checked 4x4 transform stored under `key` (missing: `InputError`)."""
    node = doc.get(key)
    if node is None:
        raise InputError(f"missing matrix {key}", file=path)
    return matrix_node(node, key, path)


def load_filestorage(path: Path) -> dict:
    """The mapping of an OpenCV FileStorage YAML (``%YAML:1.0`` directive and
    ``!!opencv-matrix`` tags accepted)."""
    lines = read_text(path).splitlines()
    if lines and lines[0].startswith("%YAML:"):  # OpenCV's non-standard directive
        lines = lines[1:]
    doc = load_yaml("\n".join(lines), path, loader=_OpenCVLoader)
    if not isinstance(doc, dict):
        raise InputError("expected a mapping (OpenCV FileStorage)", file=path)
    return doc


def read_matrix_lists(path: str | Path) -> dict[str, Array]:
    """Every list of 4x4 matrices in an OpenCV FileStorage YAML: ``{key: (n, 4, 4)}``, as
    stored (``cv::FileStorage << "key" << std::vector<cv::Mat>``)."""
    path = Path(path)
    doc = load_filestorage(path)
    out = {}
    for key, value in doc.items():
        if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            out[str(key)] = np.stack([matrix_node(v, f"{key}[{i}]", path)
                                      for i, v in enumerate(value)])
    return out


def matrix_yaml(name: str, T: Array) -> str:
    """`T` ``(4, 4)`` as a FileStorage ``!!opencv-matrix`` entry named `name`."""
    vals = ", ".join(repr(float(v)) for v in np.asarray(T, dtype=float).ravel())
    return f"{name}: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ {vals} ]\n"
