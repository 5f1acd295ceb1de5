"""Robot programs that visit a pose plan (``select-poses --program``, ``plan-check
--program``): one joint move per pose, in plan order, each followed by a wait for the
measurement. The language follows the file's suffix:

=========  ===========================  ==================================================
suffix     language                     one pose
=========  ===========================  ==================================================
.script    URScript (Universal Robots)  ``movej([q1, ..., q6], a=A, v=V)`` (rad), ``sleep(W)``
.mod       ABB RAPID                    ``MoveAbsJ [[j1,...,j6],[9E9,...]]\\NoEOffs, v100,
                                        fine, tool0;`` (deg; mm for linear axes),
                                        ``WaitTime W;``
.src       KUKA KRL                     ``PTP {A1 .., A2 .., ...}`` (deg; mm for linear
                                        axes), ``WAIT SEC W``
.yaml      ROS 2 JointTrajectory        a point per pose, ``positions: [..]`` (rad; m for
                                        prismatic joints) in flow style, zero velocities
=========  ===========================  ==================================================

Joint values are written with enough digits that reading them back loses nothing a
controller can resolve (1e-9 rad, 1e-6 deg, 1e-6 mm). A URScript program moves six
revolute joints; RAPID and KRL take up to six robot axes and six external ones (the
seventh joint on is an external axis: ``eax_a``.., ``E1``..). A trajectory controller
does not wait at a point: the YAML spaces the points by the move and the wait
(``time_from_start``) and says in its comments to send one point at a time and wait.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from kinecal.errors import InputError

__all__ = ["PROGRAM_FORMATS", "program_format", "program_text", "write_robot_program"]

#: file suffix -> language
PROGRAM_FORMATS = {".script": "urscript", ".mod": "rapid", ".src": "krl", ".yaml": "ros2",
                   ".yml": "ros2"}
#: default wait at each pose for the measurement (s)
WAIT = 2.0
#: robot axes of RAPID's robax and KRL's A1..A6; external axes after them
ROBOT_AXES = 6
EXTERNAL_AXES = 6
#: seconds a trajectory point is given to reach its pose (the YAML's time_from_start)
MOVE_SECONDS = 5.0
_UNITS_TO_MM = {"mm": 1.0, "m": 1000.0, "um": 1e-3, "cm": 10.0}


def program_format(path: str | Path, option: str = "--program") -> str:
    """The language of a program file from its suffix (module docstring)."""
    suffix = Path(path).suffix.lower()
    if suffix not in PROGRAM_FORMATS:
        raise InputError(f"cannot tell the robot language from {Path(path).name!r}: name it "
                         ".script (URScript), .mod (ABB RAPID), .src (KUKA KRL) or .yaml "
                         "(ROS 2 JointTrajectory)", option=option)
    return PROGRAM_FORMATS[suffix]


def _identifier(stem: str, limit: int) -> str:
    name = re.sub(r"[^A-Za-z0-9_]", "_", stem)[:limit]
    return name if name[:1].isalpha() else ("p" + name)[:limit]


def _lengths(values: np.ndarray, prismatic: np.ndarray, length_unit: str, to: float
             ) -> np.ndarray:
    """Prismatic columns from the model's length unit to `to` (mm per target unit)."""
    if not prismatic.any():
        return values
    if length_unit not in _UNITS_TO_MM:
        raise InputError(f"a prismatic joint in {length_unit!r}: expected mm, m, cm or um")
    out = values.copy()
    out[:, prismatic] *= _UNITS_TO_MM[length_unit] / to
    return out


def _urscript(q: np.ndarray, prismatic: np.ndarray, name: str, wait: float,
              head: list[str]) -> str:
    if q.shape[1] != 6 or prismatic.any():
        raise InputError(f"URScript moves the six revolute joints of a UR arm; this model has "
                         f"{q.shape[1]} joints{' with linear axes' if prismatic.any() else ''}",
                         option="--program")
    lines = [f"# {h}" for h in head] + [f"def {name}():"]
    for k, row in enumerate(q, 1):
        joints = ", ".join(f"{v:.9f}" for v in row)
        lines += [f"  # pose {k} of {len(q)}", f"  movej([{joints}], a=0.5, v=0.5)",
                  f'  textmsg("kinecal: pose {k} of {len(q)}: measure")', f"  sleep({wait:g})"]
    lines += ["end", f"{name}()", ""]
    return "\n".join(lines)


def _rapid(q: np.ndarray, prismatic: np.ndarray, length_unit: str, name: str, wait: float,
           head: list[str]) -> str:
    if q.shape[1] > ROBOT_AXES + EXTERNAL_AXES:
        raise InputError(f"RAPID takes {ROBOT_AXES} robot and {EXTERNAL_AXES} external axes; "
                         f"this model has {q.shape[1]} joints", option="--program")
    vals = _lengths(np.where(prismatic, q, np.degrees(q)), prismatic, length_unit, 1.0)
    lines = [f"MODULE {name}"] + [f"  ! {h}" for h in head] + ["  PROC main()"]
    for k, row in enumerate(vals, 1):
        rob = [f"{v:.6f}" for v in row[:ROBOT_AXES]] + ["0"] * (ROBOT_AXES - min(
            ROBOT_AXES, row.size))
        ext = [f"{v:.6f}" for v in row[ROBOT_AXES:]]
        ext += ["9E9"] * (EXTERNAL_AXES - len(ext))
        lines += [f"    ! pose {k} of {len(q)}",
                  f"    MoveAbsJ [[{','.join(rob)}],[{','.join(ext)}]]\\NoEOffs, v100, fine, "
                  "tool0;", f'    TPWrite "kinecal: pose {k} of {len(q)}: measure";',
                  f"    WaitTime {wait:g};"]
    lines += ["  ENDPROC", "ENDMODULE", ""]
    return "\n".join(lines)


def _krl(q: np.ndarray, prismatic: np.ndarray, length_unit: str, name: str, wait: float,
         head: list[str]) -> str:
    if q.shape[1] > ROBOT_AXES + EXTERNAL_AXES:
        raise InputError(f"KRL takes axes A1..A{ROBOT_AXES} and E1..E{EXTERNAL_AXES}; this "
                         f"model has {q.shape[1]} joints", option="--program")
    vals = _lengths(np.where(prismatic, q, np.degrees(q)), prismatic, length_unit, 1.0)
    names = [f"A{i}" for i in range(1, ROBOT_AXES + 1)] + [
        f"E{i}" for i in range(1, EXTERNAL_AXES + 1)]
    n_rob = min(ROBOT_AXES, q.shape[1])
    lines = [f"DEF {name}()"] + [f"  ; {h}" for h in head]
    lines += [f"  $VEL_AXIS[{i}] = 20" for i in range(1, n_rob + 1)]
    lines += [f"  $ACC_AXIS[{i}] = 20" for i in range(1, n_rob + 1)]
    for k, row in enumerate(vals, 1):
        axes = ", ".join(f"{names[i]} {v:.6f}" for i, v in enumerate(row))
        lines += [f"  ; pose {k} of {len(q)}", f"  PTP {{{axes}}}",
                  f"  WAIT SEC {wait:g}"]
    lines += ["END", ""]
    return "\n".join(lines)


def _ros2(q: np.ndarray, prismatic: np.ndarray, length_unit: str, names: Sequence[str],
          wait: float, head: list[str]) -> str:
    vals = _lengths(q, prismatic, length_unit, 1000.0)  # prismatic joints in metres
    zeros = "[" + ", ".join(["0.0"] * q.shape[1]) + "]"
    lines = [f"# {h}" for h in head] + [
        "# trajectory_msgs/msg/JointTrajectory: a point per pose in plan order, reached at its",
        f"# time_from_start, the next {MOVE_SECONDS:g} + {wait:g} s later; a trajectory "
        "controller moves on at once:",
        "# to measure at each pose, send one point at a time and wait there "
        f"{wait:g} s",
        "header:", "  stamp: {sec: 0, nanosec: 0}", "  frame_id: ''",
        "joint_names: [" + ", ".join(_yaml_string(n) for n in names) + "]", "points:"]
    t = 0.0
    for k, row in enumerate(vals, 1):
        t += MOVE_SECONDS
        sec = math.floor(t)
        lines += [f"  # pose {k} of {len(q)}: measure during the {wait:g} s wait",
                  "  - positions: [" + ", ".join(f"{v:.9f}" for v in row) + "]",
                  f"    velocities: {zeros}", f"    accelerations: {zeros}", "    effort: []",
                  f"    time_from_start: {{sec: {sec}, nanosec: "
                  f"{round((t - sec) * 1e9)}}}"]
        t += wait
    return "\n".join(lines) + "\n"


def _yaml_string(text: str) -> str:
    return text if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_./-]*", text) else \
        "'" + text.replace("'", "''") + "'"


def program_text(path: str | Path, q: ArrayLike, *, prismatic: ArrayLike | None = None,
                 length_unit: str = "mm", joint_names: Sequence[str] | None = None,
                 wait: float = WAIT, comment: str = "") -> str:
    """The program of `path`'s language visiting the joint values `q`.

    Parameters
    ----------
    path : str or Path
        The program file (its suffix names the language; its stem the program).
    q : array_like, shape (N, n_joints)
        Joint values in plan order (rad; prismatic joints in `length_unit`).
    prismatic : array_like of bool, shape (n_joints,), optional
        Which joints are linear.
    length_unit : str
        Length unit of the prismatic values.
    joint_names : sequence of str, optional
        The ROS joint names (default ``joint1..``).
    wait : float
        Seconds to wait at each pose for the measurement.
    comment : str
        A line for the program's header.
    """
    fmt = program_format(path)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.size == 0 or not np.isfinite(q).all():
        raise InputError("expected finite joint values for the program", option="--program")
    if not (math.isfinite(wait) and 0 <= wait <= 3600):
        raise InputError(f"expected a wait of 0 to 3600 s, got {wait}", option="--wait")
    lin = np.zeros(q.shape[1], bool) if prismatic is None else np.asarray(prismatic, bool)
    head = [line for line in (comment, f"{len(q)} poses in plan order; wait {wait:g} s at "
                              "each for the measurement") if line]
    name = _identifier(Path(path).stem, 24)
    if fmt == "urscript":
        return _urscript(q, lin, name, wait, head)
    if fmt == "rapid":
        return _rapid(q, lin, length_unit, name, wait, head)
    if fmt == "krl":
        return _krl(q, lin, length_unit, name, wait, head)
    names = list(joint_names) if joint_names else [f"joint{i}" for i in
                                                    range(1, q.shape[1] + 1)]
    if len(names) != q.shape[1]:
        raise InputError(f"{len(names)} joint names for {q.shape[1]} joints",
                         option="--joint-names")
    return _ros2(q, lin, length_unit, names, wait, head)


def write_robot_program(path: str | Path, q: ArrayLike, **kw) -> Path:
    """Write `program_text` to `path` (atomic); returns the path."""
    from kinecal._files import write_text_atomic

    text = program_text(path, q, **kw)
    write_text_atomic(path, text)
    return Path(path)
