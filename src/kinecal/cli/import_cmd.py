"""``kinecal import``: ROS bags, UR controller files and tracker exports into kinecal's
formats.

``kinecal import BAG --model MODEL --joints TOPIC [--points T | --poses T | --tf P:C]
[--images T --camera-info T] [--dwell S] --out FILE|DIR``: the rows where the robot dwells
(`kinecal.io.ros.importer`); with a ``CaptureConfig`` topic or ``--per-message``, one row
per message (a pose plan, `kinecal.io.ros.pose_plan`); ``kinecal import calibration.conf
--robot ur5 --out model.yaml``: the factory-calibrated model (`kinecal.io.ur`); ``kinecal
import SERIES.csv --out FILE.csv``: a series of the IPA UR10 data set in kinecal's
measurement CSV (`kinecal.io.ipa_export`).
"""

from __future__ import annotations

from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.cli._common import check_paths, warnings_scope
from kinecal.cli._options import (
    MODEL_HELP,
    base_link_option,
    load_model_arg,
    quiet_option,
    tip_link_option,
)
from kinecal.errors import InputError

#: files written into --out DIR with --images (the image files are named dwell_NNN.*)
FOLDER_FILES = ["camera.yaml", "stations.csv", "robot_poses.csv", "measurements.csv"]


def _is_bag(source: str) -> bool:
    from kinecal.io.ros.bag import is_bag_path

    return is_bag_path(source)


@app.command("import")
def import_(
    source: str = typer.Argument(..., help="A ROS 1 (.bag) or ROS 2 bag (folder, .db3, "
                                 ".mcap), a UR controller's calibration.conf, or a series "
                                 "of the IPA UR10 data set (.csv)."),
    out: Path = typer.Option(..., "--out", help="CSV file to write (a folder with --images; "
                             "a model YAML for calibration.conf)."),
    model: str | None = typer.Option(None, "--model", help=MODEL_HELP + " Joint order and "
                                     "units of the rows."),
    joints: str | None = typer.Option(None, "--joints", help="sensor_msgs/JointState topic."),
    points: str | None = typer.Option(None, "--points", help="geometry_msgs/PointStamped "
                                      "topic (a tracker's points)."),
    poses: str | None = typer.Option(None, "--poses", help="PoseStamped or TransformStamped "
                                     "topic."),
    tf: str | None = typer.Option(None, "--tf", help="PARENT:CHILD: the pose of CHILD in "
                                  "PARENT from /tf and /tf_static."),
    images: str | None = typer.Option(None, "--images", help="Image or CompressedImage topic "
                                      "(one image per dwell)."),
    camera_info: str | None = typer.Option(None, "--camera-info", help="CameraInfo topic "
                                           "(with --images)."),
    dwell: float = typer.Option(0.3, "--dwell", help="Minimum time (s) the joints must be "
                                "still for a row."),
    still: float = typer.Option(0.002, "--still", help="Joint speed (rad/s) below which the "
                                "joints count as still."),
    joint_names: str | None = typer.Option(None, "--joint-names", help="The bag's name of "
                                           "each model joint, in order, comma-separated "
                                           "(needed when neither the model's joint names "
                                           "nor the bag's say the order)."),
    per_message: bool = typer.Option(False, "--per-message", help="Each message of --joints "
                                     "is one pose (a capture-pose bag such as "
                                     "robot_calibration's calibration_poses.bag): one joints "
                                     "row per message, no dwell search. Implied by a "
                                     "robot_calibration_msgs/CaptureConfig topic."),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    robot: str | None = typer.Option(None, "--robot", help="calibration.conf: the UR type "
                                     "(ur3, ur3e, ur5, ur5e, ur10, ur10e, ur16e, ur20, ur30)."),
    orientation: bool = typer.Option(False, "--orientation", help="IPA UR10 series: also "
                                     "the T-Mac's orientation (a, b, c, srx, sry, srz; read "
                                     "with --orientation-format intrinsic-xyz:deg)."),
    quiet: bool = quiet_option(),
) -> None:
    """Import a ROS bag (rows where the robot dwells), a UR calibration.conf (model) or an
    IPA UR10 series (measurement CSV)."""
    bag_opts = {"--model": model, "--joints": joints, "--points": points, "--poses": poses,
                "--tf": tf, "--images": images, "--camera-info": camera_info,
                "--joint-names": joint_names, "--base-link": base_link,
                "--tip-link": tip_link, "--per-message": per_message or None}
    if orientation and (not source.lower().endswith(".csv") or _is_bag(source)):
        raise InputError("applies to a series of the IPA UR10 data set (.csv)",
                         option="--orientation")
    if robot is not None or (source.lower().endswith(".conf") and not _is_bag(source)):
        given = [k for k, v in bag_opts.items() if v is not None]
        if given:
            raise InputError(f"{given[0]} applies to bags, not to a calibration.conf",
                             option=given[0])
        if robot is None:
            raise InputError("a calibration.conf needs --robot (the UR type)", option="--robot")
        with warnings_scope():
            _import_conf(Path(source), robot, out, quiet)
        return
    if source.lower().endswith(".csv") and not _is_bag(source):
        given = [k for k, v in bag_opts.items() if v is not None]
        if given:
            raise InputError(f"{given[0]} applies to bags, not to a measurement export",
                             option=given[0])
        with warnings_scope():
            _import_ipa(Path(source), out, quiet, orientation)
        return
    with warnings_scope():
        _import_bag(source, out, bag_opts, dwell, still, quiet)


def _import_ipa(path: Path, out: Path, quiet: bool, orientation: bool) -> None:
    """The IPA UR10 accuracy data set's export (`kinecal.io.ipa_export`) as kinecal CSV."""
    from kinecal.io.ipa_export import convert_ipa_export, is_ipa_export

    check_paths({"SOURCE": path}, {"--out": out})
    if not is_ipa_export(path):
        raise InputError("not a measurement export kinecal converts: expected the IPA UR10 "
                         "export (';'-separated, shoulder_pan_joint .. wrist_3_joint and "
                         "measurement_x, _y, _z columns); kinecal reads its own CSV as it is",
                         file=path)
    n = convert_ipa_export(path, out, orientation)
    if not quiet:
        what = ("poses in mm and deg: read them with --orientation-format intrinsic-xyz:deg"
                if orientation else "positions in mm")
        typer.echo(f"wrote {out}: {n} rows (joints in deg, T-Mac {what})", err=True)


def _import_conf(path: Path, robot: str, out: Path, quiet: bool) -> None:
    from kinecal.io.models import check_model_file_name, save_model
    from kinecal.io.ur.conf import check_calibration, read_calibration_conf
    from kinecal.io.ur.robots import nominal_dh, ur_model

    nominal_dh(robot)  # an unknown type: exit 2 before anything is read
    check_model_file_name(out, "--out")
    check_paths({"SOURCE": path}, {"--out": out})
    deltas = read_calibration_conf(path)
    deviation = check_calibration(deltas, robot, path)
    model = ur_model(robot, deltas, description=f"{robot.lower()} nominal D-H plus the "
                     f"factory deltas of {path.name} (theta, a, d, alpha)")
    save_model(model, out)
    if not quiet:
        typer.echo(f"wrote {out}: {model.name}, {robot.lower()} nominal D-H plus the deltas of "
                   f"{path}: the flange within {deviation * 1000:.4g} mm of the nominal "
                   f"{robot.lower()}'s over the joint range", err=True)


def _options(o: dict, dwell: float, still: float):
    from kinecal.io.ros.importer import ImportOptions

    for opt in ("--model", "--joints"):
        if o[opt] is None:
            raise InputError(f"a bag needs {opt}", option=opt)
    kinds = [k for k in ("--points", "--poses", "--tf") if o[k] is not None]
    if len(kinds) > 1:
        raise InputError(f"{kinds[0]} and {kinds[1]}: give one measurement stream",
                         option=kinds[1])
    if (o["--images"] is None) != (o["--camera-info"] is None):
        raise InputError("--images and --camera-info go together", option="--camera-info")
    pair = None
    if o["--tf"] is not None:
        parent, sep, child = o["--tf"].partition(":")
        if not sep or not parent.strip() or not child.strip():
            raise InputError(f"{o['--tf']!r}: expected PARENT:CHILD", option="--tf")
        pair = (parent.strip().lstrip("/"), child.strip().lstrip("/"))
    names = None
    if o["--joint-names"] is not None:
        names = [n.strip() for n in o["--joint-names"].split(",") if n.strip()]
    return ImportOptions(o["--joints"], o["--points"], o["--poses"], pair, o["--images"],
                         o["--camera-info"], dwell, still, names)  # checks dwell, still, tf


def _import_bag(source: str, out: Path, o: dict, dwell: float, still: float,
                quiet: bool) -> None:
    from kinecal.io.ros.bag import bag_root

    opts = _options(o, dwell, still)
    folder = opts.images is not None
    root = bag_root(source)
    check_paths({"BAG": root, "--model": o["--model"]},
                {} if folder else {"--out": out},
                {"--out": (out, FOLDER_FILES)} if folder else None)
    if folder and out.exists() and any(out.iterdir()):
        raise InputError(f"{out} exists and is not empty: give a new folder", option="--out")
    model = load_model_arg(o["--model"], o["--base-link"], o["--tip-link"])
    if opts.joint_names is not None and len(opts.joint_names) != model.n_joints:
        raise InputError(f"expected {model.n_joints} names (one per model joint), got "
                         f"{len(opts.joint_names)}", option="--joint-names")
    if opts.joint_names is None:
        from kinecal.io.measurements import joint_names as model_joint_names

        opts.joint_names = list(model_joint_names(model)) or None
    from kinecal.io.ros.output import write_folder, write_rows

    if o["--per-message"] or _capture_topic(source, opts.joints):
        _import_plan(source, out, model, opts, o, quiet)
        return
    from kinecal.io.ros.importer import import_bag

    if folder:
        result = write_folder(source, model, opts, out)
    else:
        result = import_bag(source, model, opts)
        write_rows(out, result, model, source)
    if not quiet:
        _summary(result, opts, out)


def _capture_topic(source: str, topic: str) -> bool:
    """True when `topic` carries robot_calibration's CaptureConfig (one pose a message)."""
    from kinecal.io.ros.bag import Bag
    from kinecal.io.ros.messages import CAPTURE_CONFIG

    with Bag(source) as bag:
        return bag.topics.get(topic) == CAPTURE_CONFIG


def _import_plan(source: str, out: Path, model, opts, o: dict, quiet: bool) -> None:
    """One joints row per message of the --joints topic (a pose plan)."""
    from kinecal.io.ros.output import write_rows
    from kinecal.io.ros.pose_plan import import_pose_plan

    given = [k for k in ("--points", "--poses", "--tf", "--images") if o[k] is not None]
    if given:
        raise InputError(f"{given[0]}: a capture-pose bag gives one joints row per message "
                         "(a pose plan), without measurements", option=given[0])
    res = import_pose_plan(source, model, opts)
    write_rows(out, res, model, source)
    if not quiet:
        lines = [f"{len(res.kept)} poses from {res.samples} messages of {opts.joints} "
                 f"(one row each, mapped {res.joints_how}), {len(res.dropped)} left out"]
        lines += [f"  message {k + 1} left out: {why}" for k, why in res.dropped]
        lines.append(f"wrote {out}")
        typer.echo("\n".join(lines), err=True)


def _summary(res, opts, out: Path) -> None:
    lines = [f"{len(res.dwells)} dwells found (joints still for >= {opts.dwell:g} s in "
             f"{res.samples} samples, mapped {res.joints_how}), {len(res.kept)} kept, "
             f"{len(res.dropped)} dropped; {len(res.short)} shorter stops ignored"]
    for k, why in res.dropped:
        d = res.dwells[k]
        lines.append(f"  dropped dwell {k + 1} (+{d.start:.2f} s, still {d.span:.2f} s): {why}")
    for d in res.short:
        lines.append(f"  short stop at +{d.start:.2f} s: still for {d.span:.2f} s only "
                     f"(< --dwell {opts.dwell:g} s)")
    lines.append(f"wrote {out}")
    typer.echo("\n".join(lines), err=True)

