"""The program CSV of ``kinecal compensate``: its columns, the block-by-block stream through
`kinecal.compensation.api.compensate`, and the columns written back.

PROGRAM.csv is either a joint program (``q1..qn`` in the model's angle unit) or Cartesian
targets (``x,y,z`` and optionally ``qw,qx,qy,qz``, with optional seed joints ``q1..qn``).
Every column of the program is written back in its place (``q1..qn`` hold the joints to
command, added if absent), followed by the compensation columns (``docs/compensate.md``).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from kinecal.errors import InputError

QUATERNION = ("qw", "qx", "qy", "qz")


def program_columns(path: Path, model) -> tuple[list[str], list[str], list[str]]:
    """Header of a program CSV, checked, and its numeric columns: required and optional
    (the rows are read block by block, `kinecal.io.csvtable.read_blocks`)."""
    from kinecal.io.csvtable import check_separator
    from kinecal.io.measurements import joint_columns

    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            first = next((r for r in csv.reader(fh) if r and any(c.strip() for c in r)), None)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read CSV: {exc}", file=path) from None
    if first is None:
        raise InputError("empty file; expected a header with q1..qn or x,y,z", file=path)
    check_separator(first, path)
    header = [h.strip() for h in first]
    joints = joint_columns(header, model, path, required=False)  # q1..qn or joint names
    qcols = [c for c in header if c.startswith("q") and c[1:].isdigit()]
    if qcols and sorted(qcols) != sorted(joints):
        raise InputError(f"joint columns {', '.join(qcols)}: the model has {len(joints)} joints, "
                         f"expected {', '.join(joints)}", file=path)
    written = ["converged", "correction", "correction_angle", "residual", "residual_angle",
               "status", *(f"filtered_{c}" for c in ("x", "y", "z", *QUATERNION)),
               *(f"d{c}" for c in joints)]
    clash = [c for c in header if c in written]
    if clash:  # found before any work (a compensated program given back, say)
        raise InputError(f"column(s) {', '.join(clash)} are written by compensate (is this "
                         "an output of kinecal compensate? give the original program); "
                         "rename them", file=path)
    quat = [c for c in QUATERNION if c in header]
    if quat and len(quat) != 4:
        raise InputError(f"orientation columns {', '.join(quat)} without the others: expected "
                         "all of qw, qx, qy, qz or none", file=path)
    if all(c in header for c in "xyz"):
        required = ["x", "y", "z", *quat]
        optional = joints
    elif any(c in header for c in "xyz"):
        raise InputError("expected all of x, y, z (Cartesian targets) or none (a joint "
                         "program)", file=path)
    else:
        if joints[0] not in header:
            raise InputError(f"expected joint columns {', '.join(joints)} or target columns "
                             "x, y, z", file=path)
        required, optional = joints, []
    return header, required, optional


def fmt_float(v: float) -> str:
    return repr(float(v))


def write_program(path: Path, header: list[str], cells: list[list[str]], replace: dict,
                  extra: dict) -> None:
    """Original cells with `replace` columns overwritten (or appended), then `extra`."""
    from kinecal._files import atomic_open

    clash = [c for c in extra if c in header]
    if clash:
        raise InputError(f"program column(s) {', '.join(clash)} are written by compensate; "
                         "rename them", option="PROGRAM")
    cols = list(header) + [c for c in replace if c not in header] + list(extra)
    with atomic_open(path, "w") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        write_rows(w, header, cols, cells, replace, extra)


def write_rows(w, header: list[str], cols: list[str], cells: list[list[str]], replace: dict,
               extra: dict) -> None:
    """The rows of `cells` under the columns `cols` (`write_program`) to a csv writer."""
    for r, row in enumerate(cells):
        values = dict(zip(header, row, strict=False))
        for c, v in replace.items():
            values[c] = fmt_float(v[r])
        for c, v in extra.items():
            values[c] = v[r] if isinstance(v[r], str) else fmt_float(v[r])
        w.writerow([values.get(c, "") for c in cols])


def _bool(v: np.ndarray) -> list[str]:
    return ["true" if b else "false" for b in v]


def stream(path: Path, out: Path, header: list[str], required: list[str],
            optional: list[str], joints: list[str], arms, outputs: str | None, bar,
            angle_unit: str | None = None):
    """Compensate the program a block of `BLOCK` rows at a time, each block written as it
    is done: memory stays that of one block (the cells of a million-line program as Python
    strings, and the rows' 4x4 poses, would take gigabytes) plus a few numbers per row for
    the statistics (`ProgramRows`). Every row's answer is that of one call on the whole
    program; the per-row warnings count the whole program (`RowFindings`), issued before
    the output is committed (``--strict`` leaves no file). Joint columns in and out are in
    `angle_unit` (default the model's). Returns the `ProgramRows`."""
    from kinecal._files import atomic_open
    from kinecal.calibration.diagnostics.units import check_joint_units
    from kinecal.compensation.api import BLOCK, compensate
    from kinecal.compensation.findings import RowFindings
    from kinecal.compensation.result import ProgramRows
    from kinecal.io.csvtable import read_blocks

    nom = arms.nominal
    scale = nom.joint_scale(angle_unit)  # file units -> API units per joint
    targets = "x" in required
    findings = RowFindings()
    span = _JointSpan(nom.n_joints)
    parts: list[ProgramRows] = []
    with atomic_open(out, "w") as fh:
        w = csv.writer(fh, lineterminator="\n")
        cols = None
        for first, cells, table in read_blocks(path, required, optional, rows=BLOCK):
            if not cells:
                continue
            findings.offset = first
            q_file = np.column_stack([table[c] for c in joints]) if joints[0] in table \
                else None
            if q_file is not None:
                span.add(q_file * scale)
            try:
                if targets:
                    xyz = np.column_stack([table[c] for c in "xyz"])
                    t = (np.column_stack([xyz] + [table[c] for c in QUATERNION])
                         if "qw" in table else xyz)
                    res = compensate(arms, targets=t,
                                     seeds=None if q_file is None else q_file * scale,
                                     outputs=outputs, findings=findings)
                else:
                    res = compensate(arms, joints=q_file * scale, outputs=outputs,
                                     findings=findings)
            except InputError as exc:  # a row of the program: name the file and the row
                if exc.row is None or exc.file is not None:
                    raise
                raise InputError(exc.message, file=path, row=first + exc.row) from None
            extra = program_output_columns(res, nom, joints, angle_unit)
            replace = {c: res.q[:, k] / scale[k] for k, c in enumerate(joints)}
            if cols is None:
                cols = list(header) + [c for c in replace if c not in header] + list(extra)
                w.writerow(cols)
            write_rows(w, header, cols, cells, replace, extra)
            parts.append(res.rows())
            bar(len(cells))
        if not parts:
            raise InputError("0 data rows, expected at least 1", file=path)
        # the whole program's findings, before the file is committed (--strict)
        if span.rows:
            check_joint_units(nom, span.summary(),
                              "seed joints" if targets else "program joints", min_rows=1)
        findings.warn()
    return ProgramRows.concatenate(parts)


class _JointSpan:
    """The largest absolute reading per joint over the blocks of a program, and the row
    count: all `check_joint_units` reads of the whole program (``joint-units``)."""

    def __init__(self, n_joints: int) -> None:
        self.rows = 0
        self.largest = np.zeros(n_joints)

    def add(self, q: np.ndarray) -> None:
        self.rows += q.shape[0]
        self.largest = np.maximum(self.largest, np.abs(q).max(axis=0))

    def summary(self) -> np.ndarray:
        """Rows with the same span and (one or more than one) row count as the program."""
        return self.largest[None] if self.rows < 2 else \
            np.stack([self.largest, np.zeros_like(self.largest)])


def count_rows(path: Path) -> int:
    """Lines after the header (the progress bar's total; blank lines count too)."""
    n = 0
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 20):
            n += chunk.count(b"\n")
    return max(n - 1, 0)


def program_output_columns(res, nom, joints: list[str], angle_unit: str | None = None) -> dict:
    """The compensation columns, in the model file's units (angles in `angle_unit` when
    given)."""
    from kinecal.spatial import pq_from_transform

    extra: dict = {}
    deg = (angle_unit or nom.angle_unit) == "deg"
    angle = (lambda a: np.degrees(a)) if deg else (lambda a: a)
    if res.kind == "targets":
        f = res.filtered
        if f.ndim == 3:
            pq = pq_from_transform(f)
            names = ["x", "y", "z", *QUATERNION]
        else:
            pq, names = f, ["x", "y", "z"]
        extra.update({f"filtered_{c}": pq[:, k] for k, c in enumerate(names)})
    scale = nom.joint_scale(angle_unit)
    extra.update({f"d{c}": res.dq[:, k] / scale[k] for k, c in enumerate(joints)})
    extra["correction"] = res.correction
    if res.outputs == "pose":
        extra["correction_angle"] = angle(res.correction_rotation)
    extra["converged"] = _bool(res.converged)
    extra["residual"] = res.residual
    if res.outputs == "pose":
        extra["residual_angle"] = angle(res.residual_rotation)
    extra["status"] = [str(s) for s in res.status]
    return extra
