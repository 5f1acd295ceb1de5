"""``kinecal export``: a model or a calibration result as URDF, as a kinecal model file or as
ur_description's ``default_kinematics.yaml``; a hand-eye result as a ROS static transform
(``ros-tf``) or as the camera mount of a robot's URDF (``--camera``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from kinecal.cli._app import app
from kinecal.cli._common import check_paths, warnings_scope
from kinecal.cli._options import (
    base_link_option,
    choices,
    load_model_arg,
    single_tip,
    strict_option,
    tip_links_option,
)
from kinecal.errors import InputError

FORMATS = ("urdf", "yaml", "ur-kinematics", "ros-tf")
_SUFFIX = {".urdf": "urdf", ".yaml": "yaml", ".yml": "yaml", ".launch.py": "ros-tf"}
#: relative tolerance when checking a result's nominal values against --nominal
_NOMINAL_RTOL = 1e-9


def _format(fmt: str | None, out: Path) -> str:
    if fmt is None:
        name = out.name.lower()
        fmt = next((f for suffix, f in _SUFFIX.items() if name.endswith(suffix)), None)
        if fmt is None:
            raise InputError(f"cannot tell the format from {out.name!r}: give --format "
                             f"{' | '.join(FORMATS)}", option="--format")
    if fmt not in FORMATS:
        raise InputError(f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}",
                         option="--format")
    if fmt == "yaml" and out.name.lower().endswith((".urdf", ".xacro")):
        raise InputError(f"a model file (yaml) named {out.name!r} would be read back as a "
                         "URDF: name it .yaml, or give --format urdf", option="--format")
    return fmt


def _check_nominal(model, data: dict, path: Path) -> None:
    """Refuse a --nominal model whose values differ from those the result was computed
    from (the identified values would be applied to the wrong arm)."""
    scale = np.where(model.is_angle(), 180.0 / np.pi if model.angle_unit == "deg" else 1.0,
                     1.0)
    nominal = model.nominal * scale
    for name, entry in data["parameters"].items():
        if not isinstance(entry, dict) or "nominal" not in entry or \
                name not in model.parameter_names:
            continue
        k = model.index([name])[0]
        try:
            value = float(entry["nominal"])
        except (TypeError, ValueError):
            raise InputError(f"parameter {name!r}: expected a number 'nominal'",
                             file=path) from None
        if not np.isclose(value, nominal[k], rtol=_NOMINAL_RTOL, atol=1e-12):
            raise InputError(
                f"parameter {name}: the result's nominal value {value:.12g} is not the model's "
                f"{nominal[k]:.12g}: give --nominal the model the result was calibrated from",
                file=path)


def model_and_params(source: str, nominal: str | None, base_link: str | None,
                     tip_link: str | None):
    """The model, the identified parameter vector (or None) and the URDF file the model
    was read from (or None) behind SOURCE.

    SOURCE is a model (bundled name, YAML, URDF) or a calibration result JSON; for a
    result the nominal model is `nominal`, or the bundled model the result names.
    """
    from kinecal._files import read_json
    from kinecal.cli._serial_common import parameters_from_result
    from kinecal.io.result_values import model_for_result, serial_result_parameters

    if not source.lower().endswith(".json"):
        if nominal is not None:
            raise InputError("--nominal applies to a calibration result (RESULT.json) only",
                             option="--nominal")
        return load_model_arg(source, base_link, tip_link), None, _urdf_path(source)
    path = Path(source)
    data = read_json(path)
    serial_result_parameters(data, path)
    if nominal is None:
        from kinecal.io.models import bundled_models

        name = data.get("model")
        if name not in bundled_models():
            raise InputError(f"the result is for model {name!r}, not a bundled one: give "
                             "--nominal MODEL (the model file or URDF it was calibrated from)",
                             option="--nominal")
        nominal = str(name)
    model = model_for_result(load_model_arg(nominal, base_link, tip_link), path)
    _check_nominal(model, data, path)
    return model, parameters_from_result(model, path), _urdf_path(nominal)


def _urdf_path(spec: str) -> Path | None:
    from kinecal.io.models import is_urdf_path

    return Path(spec) if is_urdf_path(spec) else None


def _handeye_json(source: str) -> bool:
    """True when SOURCE is a hand-eye result JSON (X and setup), not a calibration result
    (an arm calibrated from images has X and setup too, and its parameters)."""
    if not source.lower().endswith(".json") or not Path(source).is_file():
        return False
    from kinecal._files import read_json

    data = read_json(Path(source))
    return isinstance(data, dict) and "X" in data and "setup" in data and \
        "parameters" not in data


@app.command("export")
def export(
    source: str = typer.Argument(..., help="Model (bundled name, YAML, URDF), calibration "
                                 "result JSON (kinecal calibrate --out) or, for ros-tf, a "
                                 "hand-eye result JSON (kinecal handeye --out)."),
    out: Path = typer.Option(..., "--out", help="File to write (.urdf, .yaml, .launch.py)."),
    fmt: str | None = typer.Option(None, "--format", metavar=choices(*FORMATS),
                                   help="ur-kinematics: ur_description's "
                                   "default_kinematics.yaml; ros-tf: a hand-eye result as a "
                                   "ROS 2 launch file (default: from the --out suffix)."),
    nominal: str | None = typer.Option(None, "--nominal", help="With a RESULT.json: the model "
                                       "it was calibrated from (default: the bundled model "
                                       "the result names)."),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
    chain_only: bool = typer.Option(False, "--chain-only", help="For a model read from a "
                                    "URDF: write only the chain, not a copy of that URDF "
                                    "(meshes, other branches) with the chain's values."),
    camera: Path | None = typer.Option(None, "--camera", help="urdf: add the camera of this "
                                       "hand-eye result JSON as a fixed joint."),
    unit: str | None = typer.Option(None, "--unit", help="ros-tf, --camera: length unit of "
                                    "the hand-eye result, mm or m (default: the result's)."),
    parent_frame: str | None = typer.Option(None, "--parent-frame", help="ros-tf, --camera: "
                                            "the frame the camera is fixed to (default: "
                                            "tool0 / base_link for ros-tf; the chain's "
                                            "flange / base link for --camera)."),
    child_frame: str | None = typer.Option(None, "--child-frame", help="ros-tf, --camera: "
                                           "the camera's (optical) frame (default "
                                           "camera_optical_frame)."),
    robot: str | None = typer.Option(None, "--robot", help="ur-kinematics: the UR type whose "
                                     "link frames the export keeps (default: the type the "
                                     "model is a calibration of)."),
    strict: bool = strict_option(),
) -> None:
    """Write a model, or a calibrated one, as URDF (metres, radians), as a model file or as
    ur_description's kinematics file; a hand-eye result as a ROS static transform.

    A model read from a URDF is written into a copy of that URDF: its chain's joint origins
    take the calibrated values, a tool link (and the measurement frame) are added, and
    everything else (meshes, inertias, other branches) is kept.
    """
    fmt = _format(fmt, out)
    check_paths({"SOURCE": source, "--nominal": nominal, "--camera": camera}, {"--out": out})
    from kinecal.cli.systems import is_system_arg, system_export

    if is_system_arg(nominal or source, base_link, tip_link):  # the whole tree of a system
        if camera is not None or robot is not None:
            raise InputError("does not apply to a robot system",
                             option="--camera" if camera is not None else "--robot")
        with warnings_scope(strict):
            system_export(source, nominal, base_link, tip_link, out, fmt, chain_only)
        return
    tip_link = single_tip(tip_link)
    if fmt == "ros-tf":
        _export_ros_tf(source, out, unit, parent_frame, child_frame, strict)
        return
    _check_arm_source(source)
    for opt, value, needs, words in (
            ("--camera", camera, "urdf", "--camera adds a camera mount to a URDF: give "
             "--format urdf"),
            ("--chain-only", chain_only, "urdf", "--chain-only applies to --format urdf"),
            ("--robot", robot, "ur-kinematics", "--robot applies to --format ur-kinematics")):
        if value and fmt != needs:
            raise InputError(words, option=opt)
    with warnings_scope(strict):
        model, params, urdf = model_and_params(source, nominal, base_link, tip_link)
        if chain_only and urdf is None:  # it would change nothing
            raise InputError("applies to a model read from a URDF (the chain alone instead "
                             f"of a copy of that URDF); {model.name!r} is a "
                             f"{model.convention} model, not read from a URDF",
                             option="--chain-only")
        _warn_joint_errors(model, fmt)
        what = f"model {model.name}" if params is None else f"{source} (calibrated {model.name})"
        if fmt == "ur-kinematics":
            _export_ur(model, params, out, what, robot)
            return
        if fmt == "urdf":
            _export_urdf(model, params, urdf, out, what, chain_only,
                         (camera, unit, parent_frame, child_frame))
            unit_text = "metres, radians"
        else:
            from kinecal.io.models import save_model

            target = model if params is None else model.with_params(
                params, name=f"{model.name}-calibrated")
            save_model(target, out)
            unit_text = f"{model.length_unit}, {model.angle_unit}"
        typer.echo(f"wrote {out} ({fmt}, {model.n_joints} joints, {unit_text}) from {what}",
                   err=True)


def _check_arm_source(source: str) -> None:
    """Refuse, with what export takes, a SOURCE that is not a serial arm: a hand-eye result
    (exported with ros-tf or --camera) or a Stewart-platform geometry."""
    if _handeye_json(source):
        raise InputError(f"{source} is a hand-eye calibration result, not an arm's (kinecal "
                         "calibrate --out): export it with --format ros-tf, or as the camera of "
                         f"a robot's URDF with kinecal export MODEL --camera {source} --format "
                         "urdf", option="SOURCE")
    from kinecal.io.bundled import bundled_index

    if bundled_index().get(source) == "geometry" or (
            source.lower().endswith((".yaml", ".yml")) and _is_geometry_file(source)):
        raise InputError(f"{source} is a Stewart-platform geometry: export writes serial arms "
                         "(a model: bundled name, YAML or URDF; or a calibration result JSON "
                         "of kinecal calibrate --out) and hand-eye results (--format ros-tf, "
                         "--camera); a calibrated Stewart geometry is written by kinecal "
                         "stewart calibrate --geometry-out", option="SOURCE")


def _is_geometry_file(path: str) -> bool:
    from kinecal.io.bundled import machine_kind

    return Path(path).is_file() and machine_kind(Path(path)) == "geometry"


def _warn_joint_errors(model, fmt: str) -> None:
    """``joint-errors-not-exported`` when a URDF or UR file cannot carry the model's
    joint-error terms."""
    if fmt in ("urdf", "ur-kinematics") and model.joint_errors is not None:
        from kinecal.diagnostics import warn

        warn("joint-errors-not-exported",
             f"the model's {len(model.parameter_names) - model._n_geometric} joint-error "
             f"coefficients (compliance, harmonics, scale) have no {fmt} equivalent: the "
             "file carries the geometry only; use the model file (--format yaml) for fk, "
             "ik and compensate")


def _export_urdf(model, params, urdf: Path | None, out: Path, what: str, chain_only: bool,
                 cam: tuple) -> None:
    """Write the URDF of `model` (into a copy of its URDF `urdf`), with the camera mount of
    a hand-eye result when ``cam[0]`` names one."""
    from kinecal._files import write_text_atomic
    from kinecal.io.urdf_export import urdf_string
    from kinecal.io.urdf_patch import patched_urdf

    comment = f"written by kinecal export from {what}; lengths in metres, angles in radians"
    if urdf is not None and not chain_only:
        text = patched_urdf(urdf, model, params, comment=comment + f", into {urdf.name}")
    else:
        text = urdf_string(model, params, comment=comment)
    camera, unit, parent, child = cam
    if camera is not None:
        from kinecal.io.ros.static_tf import (
            DEFAULT_CHILD,
            check_frame,
            metres_in_cell,
            metres_per_unit,
            read_handeye_result,
        )
        from kinecal.io.urdf_camera import add_camera_mount

        X, setup, length_unit = read_handeye_result(camera)
        scale = metres_per_unit(length_unit, unit, camera)
        base, flange = _mount_links(model, params, camera)
        given = parent is not None
        parent = (flange if setup == "eye-in-hand" else base) if parent is None else \
            check_frame(parent, "--parent-frame")
        child = DEFAULT_CHILD if child is None else check_frame(child, "--child-frame")
        text = add_camera_mount(text, parent, child, metres_in_cell(X, scale, camera))
        typer.echo(f"camera mount ({setup}, {camera}): link {child} fixed to {parent}"
                   + ("" if given or setup != "eye-in-hand" else
                      f" (the frame X is relative to; ROS-Industrial drivers publish the "
                      f"flange as tool0, the default parent of --format ros-tf: give "
                      f"--parent-frame {parent} there to hang the camera from this URDF's "
                      "link)"), err=True)
    else:
        for opt, v in (("--unit", unit), ("--parent-frame", parent), ("--child-frame", child)):
            if v is not None:
                raise InputError(f"{opt} applies to --format ros-tf and to --camera",
                                 option=opt)
    write_text_atomic(out, text)


def _mount_links(model, params, camera: Path) -> tuple[str, str]:
    """The URDF links a camera of `camera` hangs from: (base side, flange side). A hand-eye
    result's X is relative to the robot's flange or base (the chain's flange and base
    links); an arm calibrated from images (``calibrate --images``) has X relative to the
    model's end frame and measurement frame (the ``tool`` and first links)."""
    from kinecal._files import read_json
    from kinecal.io.urdf_camera import chain_links

    data = read_json(camera)
    if isinstance(data, dict) and data.get("kind") == "camera":
        from kinecal.io.urdf_export import urdf_joints

        p = model.nominal if params is None else params
        joints = urdf_joints(model, p)
        return joints[0].parent, joints[-1].child
    return chain_links(model, params)


def _export_ur(model, params, out: Path, what: str, robot: str | None) -> None:
    """Write ur_description's default_kinematics.yaml of a UR-type model."""
    from kinecal.io.ur.kinematics import save_ur_kinematics, ur_kinematics

    _, ref = ur_kinematics(model, params, robot)
    comment = (f"written by kinecal export from {what}: ur_description kinematics (metres, "
               "radians);\nchain from base_link_inertia (UR's base frame, D-H frame 0) to "
               "wrist_3 = tool0 (D-H frame 6); the model's base and tool are not part of it\n"
               + (f"link frames kept next to the nominal {ref}'s" if ref else
                  "no UR type the model is a calibration of: plain regrouping of the D-H table"))
    save_ur_kinematics(out, model, params, ref, comment)
    typer.echo(f"wrote {out} (ur-kinematics, {model.name}, metres, radians; reference "
               f"{ref or 'none'}) from {what}; load it with ur_robot_driver's "
               "kinematics_params_file (ROS 2) or kinematics_config (ROS 1)", err=True)


def _export_ros_tf(source: str, out: Path, unit: str | None, parent: str | None,
                   child: str | None, strict: bool) -> None:
    """Write a hand-eye result as a ROS 2 launch file; print the frames and command."""
    with warnings_scope(strict):
        _write_ros_tf(source, out, unit, parent, child)


def _write_ros_tf(source: str, out: Path, unit: str | None, parent: str | None,
                  child: str | None) -> None:
    from kinecal._files import write_text_atomic
    from kinecal.io.ros.static_tf import (
        metres_in_cell,
        metres_per_unit,
        read_handeye_result,
        static_transform,
    )

    path = Path(source)
    X, setup, length_unit = read_handeye_result(path)
    X_m = metres_in_cell(X, metres_per_unit(length_unit, unit, path), path)
    tf = static_transform(X_m, setup, 1.0, parent, child)
    write_text_atomic(out, tf.launch_file(comment=f"written by kinecal export from {source} "
                                          f"({setup}); lengths in metres"))
    typer.echo(tf.words())
    typer.echo(tf.command())
    typer.echo(f"wrote {out} (ros-tf launch file, {setup}): ros2 launch {out}", err=True)
