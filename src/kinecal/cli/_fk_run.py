"""The body of ``kinecal fk`` (serial arms; robot systems go to `kinecal.cli.systems`),
free of typer: `kinecal.cli._direct` runs it without building the typer command."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from kinecal.cli._common import resolve_data_path, warnings_scope
from kinecal.cli._options import check_angle_unit, load_model_arg, single_tip
from kinecal.errors import InputError

__all__ = ["run_fk"]


def run_fk(model: str, base_link: str | None, tip_link: list[str] | None, joints: str,
           pose: bool, params: Path | None, tip: str | None, strict: bool, quiet: bool,
           angle_unit: str | None) -> None:
    """``kinecal fk`` (the options as in `kinecal.cli.fk.fk`)."""
    check_angle_unit(angle_unit)
    from kinecal.io.systems import is_system_spec

    if is_system_spec(model, base_link, tip_link or ()):
        from kinecal.cli.systems import system_fk

        return system_fk(dict(locals()))
    if tip is not None:
        raise InputError("applies to a robot system (docs/systems.md)", option="--tip")
    tip_link = single_tip(tip_link)
    from kinecal.calibration.diagnostics.units import check_joint_limits, check_joint_units
    from kinecal.io.measurements import read_joints, read_markers

    with warnings_scope(strict):
        m = load_model_arg(model, base_link, tip_link)
        if params is not None:  # imported here: a plain fk reads no result
            from kinecal.cli._serial_common import parameters_from_result
            from kinecal.io.result_values import model_for_result, read_result_envelope

            m = model_for_result(m, params)
        path = resolve_data_path(joints, "JOINTS")
        q = read_joints(path, m, angle_unit=angle_unit)
        marker = read_markers(path, m)[0] if m.marker_names else None
        check_joint_limits(m, q, "joint readings")
        check_joint_units(m, q, "joint readings")
        p = None if params is None else parameters_from_result(m, params)
        # the joint readings the calibration saw: the result's, or those of the terms of a
        # calibrated model file
        envelope = (read_result_envelope(m, params) if params is not None else
                    None if m.joint_errors is None else m.joint_errors.envelope)
        if envelope is not None:
            from kinecal.calibration.diagnostics.envelope import check_calibrated_range

            check_calibrated_range(q, envelope, m, "joint readings")
    T = m.fk(q, p, marker)
    header = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if pose else [])
    out = T[:, :3, 3]
    if pose:
        from kinecal.spatial import quaternion_from_matrix

        out = np.column_stack([out, quaternion_from_matrix(T[:, :3, :3])])
    # shortest round-trip digits (repr): what the API computes, bit for bit, in any unit
    lines = [",".join(header)] + [",".join(map(repr, row)) for row in out.tolist()]
    sys.stdout.write("\n".join(lines) + "\n")
