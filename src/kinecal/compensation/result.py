"""Result of `kinecal.compensation.api.compensate`: one row per program line."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.kinematics.serial.ik import STATUS, IKResult
from kinecal.metrology.units import display_unit

__all__ = ["CompensationResult", "ProgramRows"]

Array = NDArray[np.float64]


@dataclass(frozen=True, repr=False)
class CompensationResult:
    """Outcome of `compensate`, one row per program line.

    Attributes
    ----------
    kind : {"joints", "targets"}
        What the program gave.
    outputs : {"pose", "position"}
        What was compensated: the full tool pose, or the tool point only.
    q : ndarray, shape (N, n_joints)
        Joints to command (rad; prismatic joints in the length unit).
    q_nominal : ndarray, shape (N, n_joints)
        Joints an uncompensated controller commands: the program's joints, or the nominal
        inverse kinematics of the targets.
    dq : ndarray, shape (N, n_joints)
        ``q - q_nominal``.
    intended : ndarray, shape (N, 4, 4) or (N, 3)
        The poses (or points) the program means, in the program's frame.
    filtered : ndarray, shape (N, 4, 4) or (N, 3)
        Nominal model at `q`: the targets to send to a controller running its nominal model.
    correction, correction_rotation : ndarray, shape (N,)
        Distance (length unit) and angle (rad; NaN for position compensation) between
        `filtered` and `intended`.
    error_before, error_before_rotation : ndarray, shape (N,)
        Calibrated model at `q_nominal` against `intended`: the error the uncompensated
        program is predicted to have.
    residual, residual_rotation : ndarray, shape (N,)
        Calibrated model at `q` against `intended` (the IK residual).
    converged : ndarray of bool, shape (N,)
        The calibrated model reaches the intent at `q` within the IK tolerances.
    status : ndarray of str, shape (N,)
        IK status per row (`kinecal.kinematics.serial.ik.STATUS`).
    nominal_converged : ndarray of bool, shape (N,)
        Targets only: the nominal inverse kinematics converged (all True for joint programs).
    ik : IKResult
        The inverse kinematics on the calibrated model.
    length_unit : str
    prismatic : ndarray of bool, shape (n_joints,), optional
        True for prismatic joints (their `dq` is a length, not an angle).
    """

    kind: str
    outputs: str
    q: Array
    q_nominal: Array
    dq: Array
    intended: Array
    filtered: Array
    correction: Array
    correction_rotation: Array
    error_before: Array
    error_before_rotation: Array
    residual: Array
    residual_rotation: Array
    converged: NDArray[np.bool_]
    status: NDArray[np.str_]
    nominal_converged: NDArray[np.bool_]
    ik: IKResult
    length_unit: str = ""
    prismatic: NDArray[np.bool_] | None = None

    def __len__(self) -> int:
        return int(self.q.shape[0])

    def rows(self) -> ProgramRows:
        """The per-row numbers the statistics and the summary read (`ProgramRows`)."""
        return ProgramRows(self.kind, self.outputs, self.correction, self.correction_rotation,
                           self.error_before, self.residual, self.residual_rotation,
                           self.converged, self.status, self.dq, self.length_unit,
                           self.prismatic)

    def __repr__(self) -> str:
        ok = self.converged
        text = (f"<CompensationResult {len(self)} {self.kind} ({self.outputs}): "
                f"{int(ok.sum())} converged")
        if ok.any():
            u, f = (display_unit(self.length_unit, None, self.correction[ok])
                    if self.length_unit else ("length unit", 1.0))
            text += f", correction max {self.correction[ok].max() * f:.4g} {u}"
        return text + ">"

    def summary(self, unit: str | None = None) -> str:
        """A few lines: rows, convergence, size of the corrections and of the residuals;
        lengths in `unit` (``mm``, ``um``, ``m``; by default the model's, millimetres for a
        model in metres: `kinecal.metrology.units.display_unit`)."""
        return self.rows().summary(unit)

    def joint_motion(self) -> tuple[Array, Array]:
        """Largest joint change per row ``(N,)``: over the revolute joints (rad) and over
        the prismatic ones (length unit); zeros where the arm has none of that kind."""
        return self.rows().joint_motion()

    def stats(self) -> dict[str, Any]:
        """JSON-ready statistics: counts, corrections, residuals."""
        return self.rows().stats()


@dataclass(frozen=True)
class ProgramRows:
    """Per-row numbers of a compensated program (see `CompensationResult`), without the
    poses: what its statistics and summary read, a few numbers per row. A program
    compensated block by block (``kinecal compensate``) keeps these for every block and
    concatenates them (`concatenate`); the statistics are then those of one call."""

    kind: str
    outputs: str
    correction: Array
    correction_rotation: Array
    error_before: Array
    residual: Array
    residual_rotation: Array
    converged: NDArray[np.bool_]
    status: NDArray[np.str_]
    dq: Array
    length_unit: str = ""
    prismatic: NDArray[np.bool_] | None = None

    @classmethod
    def concatenate(cls, parts: list[ProgramRows]) -> ProgramRows:
        """The rows of consecutive blocks of one program, in order (at least one)."""
        first = parts[0]
        arrays = {f: np.concatenate([getattr(p, f) for p in parts]) for f in (
            "correction", "correction_rotation", "error_before", "residual",
            "residual_rotation", "converged", "status", "dq")}
        return dataclasses.replace(first, **arrays)

    def __len__(self) -> int:
        return int(self.converged.shape[0])

    def counts(self) -> dict[str, int]:
        """Rows per IK status (`kinecal.kinematics.serial.ik.STATUS`, zeros included)."""
        return {s: int(np.count_nonzero(self.status == s)) for s in STATUS}

    def summary(self, unit: str | None = None) -> str:
        """A few lines: rows, convergence, size of the corrections and of the residuals;
        lengths in `unit` (see `CompensationResult.summary`)."""
        n = len(self)
        if self.length_unit:
            unit, f = display_unit(self.length_unit, unit, self.correction[self.converged])
        else:
            unit, f = "length unit", 1.0
        ok = self.converged
        lines = [f"compensated {n} {'joint-program rows' if self.kind == 'joints' else 'targets'}"
                 f" ({self.outputs}): {int(ok.sum())} converged"]
        rows = self._statistics_rows()
        which = " (converged rows)" if not ok.all() else ""
        if n and ok.any():
            c = self.correction[rows] * f
            lines.append(f"correction{which}: mean {c.mean():.4g} {unit}, max {c.max():.4g} "
                         f"{unit}; " + self._joint_motion((unit, f), rows))
            if self.outputs == "pose":
                a = np.degrees(self.correction_rotation[rows])
                lines.append(f"correction angle{which}: mean {a.mean():.4g} deg, max "
                             f"{a.max():.4g} deg")
            if ok.any():
                lines.append(f"residual (converged rows): max {self.residual[ok].max() * f:.3g} "
                             f"{unit}"
                             + (f", {self.residual_rotation[ok].max():.3g} rad"
                                if self.outputs == "pose" else ""))
        for s, k in self.counts().items():
            if k and s != "converged":
                lines.append(f"  {s}: {k} rows")
        return "\n".join(lines)

    def _statistics_rows(self) -> NDArray[np.bool_]:
        """The rows the correction statistics describe (summary and JSON alike): those that
        converged, when some did; a failed row's "correction" is the distance to wherever
        its solver stopped (a target out of reach gave "mean 1320 mm")."""
        ok = self.converged
        return ok if ok.any() and not ok.all() else np.ones(len(self), dtype=bool)

    def _prismatic(self) -> NDArray[np.bool_]:
        return (np.zeros(self.dq.shape[1], dtype=bool) if self.prismatic is None
                else np.asarray(self.prismatic, dtype=bool))

    def joint_motion(self) -> tuple[Array, Array]:
        """Largest joint change per row ``(N,)``: over the revolute joints (rad) and over
        the prismatic ones (length unit); zeros where the arm has none of that kind."""
        pris = self._prismatic()
        dq = np.abs(self.dq)
        n = dq.shape[0]
        rev = dq[:, ~pris].max(axis=1) if (~pris).any() else np.zeros(n)
        lin = dq[:, pris].max(axis=1) if pris.any() else np.zeros(n)
        return rev, lin

    def _joint_motion(self, shown: tuple[str, float], rows: NDArray[np.bool_]) -> str:
        """``joints up to 0.8 deg`` (revolute in degrees, prismatic in the length unit
        `shown`, ``(name, factor)``) over `rows`."""
        unit, f = shown
        pris = self._prismatic()
        rev, lin = (m[rows] for m in self.joint_motion())
        parts = []
        if (~pris).any():
            parts.append(f"{np.degrees(rev.max()):.4g} deg")
        if pris.any():
            parts.append(f"{lin.max() * f:.4g} {unit} (prismatic)")
        return "joints up to " + ", ".join(parts)

    def stats(self) -> dict[str, Any]:
        """JSON-ready statistics: counts, corrections, residuals."""
        def s(x: Array) -> dict[str, float] | None:
            x = x[np.isfinite(x)]
            if x.size == 0:
                return None
            return {"mean": float(x.mean()), "rms": float(np.sqrt(np.mean(x ** 2))),
                    "max": float(x.max())}

        rows = self._statistics_rows()
        rev, lin = self.joint_motion()
        return {"kind": self.kind, "outputs": self.outputs, "rows": len(self),
                "converged": int(self.converged.sum()), "status": self.counts(),
                "length_unit": self.length_unit,
                # like the summary: corrections over the converged rows when some failed
                "correction_rows": "all" if rows.all() else "converged",
                "correction": s(self.correction[rows]),
                "correction_rotation_rad": s(self.correction_rotation[rows]),
                "error_before": s(self.error_before),
                "residual": s(self.residual[self.converged]),
                "joint_correction_rad": s(rev[rows]) if len(self) else None,
                **({"joint_correction_length": s(lin[rows]) if len(self) else None}
                   if self._prismatic().any() else {})}
