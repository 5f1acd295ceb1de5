"""The ``--program`` option of the commands that plan poses (``select-poses``,
``plan-check``): a robot program visiting them (`kinecal.io.programs`). No command is
registered here."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["check_program_for", "program_option", "wait_option", "write_program_for"]


def program_option() -> Any:
    """The ``--program`` option."""
    import typer

    return typer.Option(None, "--program", help="Also a robot program visiting the poses in "
                        "order, a wait at each: .script (URScript), .mod (ABB RAPID), .src "
                        "(KUKA KRL) or .yaml (ROS 2 JointTrajectory).")


def wait_option() -> Any:
    """The ``--wait`` option of ``--program``."""
    import typer

    return typer.Option(2.0, "--wait", help="With --program: seconds at each pose for the "
                        "measurement.")


def check_program_for(path: Path | None, model: Any, wait: float) -> None:
    """Refuse, before any work, a program the language cannot write for `model` (a URScript
    of seven joints, an unknown suffix, a wait out of range)."""
    if path is None:
        return
    import numpy as np

    from kinecal.io.programs import program_text

    program_text(path, np.zeros((1, model.n_joints)), prismatic=model.is_prismatic(),
                 length_unit=model.length_unit, wait=wait)


def write_program_for(path: Path, model: Any, q: Any, wait: float, comment: str) -> None:
    """The robot program of joint values `q` (API units) for `model`; ROS joint names are
    the model's (a URDF's), a UR arm's driver names for a bundled UR model, else
    ``joint1..``."""
    from kinecal.io.measurements import joint_names
    from kinecal.io.programs import write_robot_program

    names = list(joint_names(model)) or None
    if names is None and model.n_joints == 6 and model.name.startswith("ur"):
        from kinecal.io.ros.joints import UR_JOINTS

        names = list(UR_JOINTS)
    write_robot_program(path, q, prismatic=model.is_prismatic(),
                        length_unit=model.length_unit, joint_names=names, wait=wait,
                        comment=comment)
