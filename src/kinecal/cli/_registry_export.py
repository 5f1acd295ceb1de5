"""``kinecal registry export``: a stored calibration written by `kinecal export`'s writers
(its result and model put in a temporary folder first). No command is registered here."""

from __future__ import annotations

from pathlib import Path

import typer

__all__ = ["export_event"]


def _ros_tf(result: Path, out: Path, what: str) -> None:
    """A stored hand-eye result as a ROS 2 launch file (as ``kinecal export --format
    ros-tf``), its comment naming the record."""
    from kinecal._files import write_text_atomic
    from kinecal.io.ros.static_tf import (
        metres_in_cell,
        metres_per_unit,
        read_handeye_result,
        static_transform,
    )

    X, setup, length_unit = read_handeye_result(result)
    tf = static_transform(metres_in_cell(X, metres_per_unit(length_unit, None, result),
                                         result), setup, 1.0, None, None)
    write_text_atomic(out, tf.launch_file(comment=f"written by kinecal registry export from "
                                          f"{what} ({setup}); lengths in metres"))
    typer.echo(tf.words())
    typer.echo(tf.command())


def export_event(ev: dict, fmt: str, out: Path, what: str) -> None:
    """Write the stored calibration `ev` as `fmt` with `kinecal export`'s writers: its
    result and model written to a temporary folder first."""
    import tempfile

    from kinecal.cli.export import _export_ur, _export_urdf, model_and_params
    from kinecal.registry.store import dumps

    with tempfile.TemporaryDirectory(prefix="kinecal-export-") as tmp:
        result = Path(tmp) / "result.json"
        result.write_text(dumps(ev["document"]), encoding="utf-8")
        if fmt == "ros-tf":
            _ros_tf(result, out, what)
            return
        model = Path(tmp) / (Path(ev["model_file"]).name or "model.yaml")
        model.write_text(ev["model_text"], encoding="utf-8")
        m, params, urdf = model_and_params(str(result), str(model), ev.get("base_link"),
                                           ev.get("tip_link"))
        if fmt == "ur-kinematics":
            _export_ur(m, params, out, what, None)
            return
        if fmt == "urdf":
            _export_urdf(m, params, urdf, out, what, False, (None, None, None, None))
        else:
            from kinecal.io.models import save_model

            save_model(m.with_params(params, name=f"{m.name}-calibrated"), out)
    typer.echo(f"wrote {out} ({fmt}) from {what}", err=True)
