"""``kinecal handeye`` and ``kinecal handeye-poses`` (DESIGN sec. 4; Li, Xiao, Lai and Hu
(2024))."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from kinecal._limits import check_count
from kinecal.cli._app import app
from kinecal.cli._common import (
    check_paths,
    echo_json,
    report_record,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._options import (
    choices,
    instrument_option,
    note_option,
    operator_option,
    quiet_option,
    report_option,
    seed_option,
    strict_option,
)
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

#: bundled recordings addressable by name, with the setup they were recorded in
_BUNDLED_SETUP = {"handeye-camodocal": "eye-to-hand", "handeye-tabb1": "eye-in-hand"}
#: their length units (files carry none; labels of the output only)
_BUNDLED_UNIT = {"handeye-camodocal": "m", "handeye-tabb1": "mm"}


def resolve_pairs(spec: str) -> tuple[Path, str | None]:
    """Path of a pairs file and its default setup: a path, ``NAME`` or ``NAME:pairs``."""
    path = Path(spec)
    if path.exists():
        return path, None
    from kinecal.datasets import DATASETS, dataset_dir

    name, _, part = spec.partition(":")
    info = DATASETS.get(name)
    if info is not None and "pairs" in info["parts"] and part in ("", "pairs"):
        return dataset_dir(name) / info["parts"]["pairs"], _BUNDLED_SETUP.get(name)
    raise InputError(f"file not found (nor a bundled hand-eye recording: "
                     f"{', '.join(_BUNDLED_SETUP)})", file=spec, option="PAIRS")


def _check_pairs_mode(method: str, refine: str, pairs_mode: str) -> None:
    """``--pairs`` selects motion pairs: used by the AX = XB closed forms and the
    metaheuristic refiners, not by the AX = ZB methods (shah, li) refined otherwise."""
    from kinecal.calibration.handeye import axxb

    if pairs_mode != "all" and method not in axxb.SOLVERS and refine not in ("igwo",
                                                                             "dlh-gwo-de"):
        raise InputError(f"motion pairs apply to the AX = XB methods and the igwo / "
                         f"dlh-gwo-de refiners, not to method {method} with refine {refine}",
                         option="--pairs")


def _format_matrix(X: np.ndarray) -> str:
    return "\n".join("  [" + ", ".join(f"{v:12.6f}" for v in row) + "]" for row in X)


def camera_height_option() -> float | None:
    """``--camera-height``: X's translation along a SCARA's one rotation axis."""
    return typer.Option(None, "--camera-height", help="Robots that turn about one axis only "
                        "(SCARA, 4-axis): X's translation along that axis, which the poses "
                        "cannot show: the camera's offset from the flange origin (eye-in-hand) "
                        "or its height in the base frame (eye-to-hand), measured along the "
                        "base's axis direction (+z for an upright SCARA).")


def board_contact_option() -> str | None:
    """``--board-contact``: a point of the board plane that fixes a SCARA's height."""
    return typer.Option(None, "--board-contact", help="Instead of --camera-height: X,Y,Z of a "
                        "point of the board's printed plane, touched by the tool tip, in the "
                        "base frame (eye-in-hand) or flange frame (eye-to-hand).")


def parse_contact(text: str | None) -> np.ndarray | None:
    """``X,Y,Z`` of ``--board-contact`` as an array, or `InputError`."""
    if text is None:
        return None
    from kinecal.calibration.handeye.scara import MAX_LENGTH

    try:
        P = np.array([float(v) for v in text.split(",")])
    except ValueError:
        P = np.zeros(0)
    if P.shape != (3,) or not np.all(np.abs(P) <= MAX_LENGTH):
        raise InputError(f"{text!r}: expected X,Y,Z (three numbers within +-{MAX_LENGTH:g}, "
                         "e.g. 450,0,-12.5)", option="--board-contact")
    return P


def one_axis_lines(one: dict | None, unit: str) -> list[str]:
    """Summary lines explaining a one-axis (SCARA) solution, none otherwise."""
    if not one:
        return []
    a = np.round(one["axis_base"], 3) + 0.0  # no "-0.000"

    def length(v: float) -> str:
        return f"{round(float(v), 6) + 0.0:.6g} {unit}"

    src = {"camera-height": "from --camera-height", "board-contact": "from --board-contact",
           "none": "ASSUMED 0 (give --camera-height or --board-contact)"}[one["height_from"]]
    return [f"rotations about one axis only ({a[0]:+.3f}, {a[1]:+.3f}, {a[2]:+.3f} in the base "
            f"frame; SCARA): X's translation along it is not in the data, {src}; camera "
            f"{length(one['camera_height'])} ({one['camera_height_is']}), board origin "
            f"{length(one['board_height'])} ({one['board_height_is']}) along the axis"]


_FORMAT_HELP = ("matrix: 4x4, rotvec: UR, euler-zyx: KUKA A, B, C; append :deg for angles "
                "in degrees (e.g. euler-zyx:deg).")
#: the metavar of --robot-format and --target-format
_FORMATS = choices("auto", "quaternion", "matrix", "rotvec", "euler-zyx", "rpy") + "[:deg]"
#: the metavar of --method (kinecal.calibration.handeye.METHODS)
HANDEYE_METHODS = ("tsai", "park", "horaud", "andreff", "daniilidis", "shah", "li")


def read_pairs(pairs: str | None, robot_poses: Path | None, target_poses: Path | None,
               robot_format: str, target_format: str, invert_robot: bool,
               invert_target: bool):
    """Pose pairs from PAIRS or from --robot-poses and --target-poses, in the formats and
    directions the options give; returns ``(flange2base, target2cam, source, setup)``."""
    from kinecal.io.handeye import read_handeye_files, read_handeye_pairs
    from kinecal.io.poses import PoseFormat

    robot = PoseFormat.parse(robot_format, invert_robot, "--robot-format")
    target = PoseFormat.parse(target_format, invert_target, "--target-format")
    if pairs is not None:
        if robot_poses is not None or target_poses is not None:
            raise InputError("give PAIRS or --robot-poses and --target-poses, not both",
                             option="--robot-poses")
        path, default_setup = resolve_pairs(pairs)
        F, C = read_handeye_pairs(path, robot, target)
        return F, C, str(path), default_setup
    if robot_poses is None or target_poses is None:
        raise InputError("expected PAIRS, or both --robot-poses and --target-poses",
                         option="--target-poses" if robot_poses else "--robot-poses")
    F, C = read_handeye_files(robot_poses, target_poses, robot, target)
    return F, C, f"{robot_poses} + {target_poses}", None


@app.command("handeye")
def handeye(
    pairs: str | None = typer.Argument(
        None, help="Pose pairs: CSV, OpenCV FileStorage YAML, or a bundled name "
        "(handeye-camodocal). Or give --robot-poses and --target-poses."
    ),
    robot_poses: Path | None = typer.Option(
        None, "--robot-poses", help="Robot poses (flange2base; base2gripper with "
        "--invert-robot), one per row of a CSV or a FileStorage list of 4x4 matrices."),
    target_poses: Path | None = typer.Option(
        None, "--target-poses", help="Target poses in the camera (target2cam; cam2target "
        "with --invert-target), as --robot-poses, one per station in the same order."),
    robot_format: str = typer.Option("auto", "--robot-format", metavar=_FORMATS,
                                     help="Rotation columns of the robot poses; " + _FORMAT_HELP),
    target_format: str = typer.Option("auto", "--target-format", metavar=_FORMATS,
                                      help="Rotation columns of the target poses; "
                                      + _FORMAT_HELP),
    invert_robot: bool = typer.Option(False, "--invert-robot", help="The robot poses are "
                                      "base2gripper (the base in the flange frame): invert."),
    invert_target: bool = typer.Option(False, "--invert-target", help="The target poses are "
                                       "cam2target: invert."),
    setup: str | None = typer.Option(
        None, "--setup", metavar=choices("eye-in-hand", "eye-to-hand"), help="Camera on the "
        "flange (default) or fixed (default of the bundled camodocal recording)."
    ),
    method: str = typer.Option("park", "--method", metavar=choices(*HANDEYE_METHODS),
                               help="Closed-form solution."),
    refine: str = typer.Option("lm", "--refine",
                               metavar=choices("none", "lm", "igwo", "dlh-gwo-de"),
                               help="Refinement of the closed form (lm: robust)."),
    pairs_mode: str = typer.Option("all", "--pairs", metavar=choices("all", "consecutive"),
                                   help="Motion pairs of the AX=XB closed forms."),
    seed: int = seed_option("Random seed (metaheuristic refiners; an integer >= 0)."),
    unit: str | None = typer.Option(None, "--unit", help="Length unit of the poses, for the "
                                    "output labels (default: the bundled recording's, else "
                                    "'input unit')."),
    camera_height: float | None = camera_height_option(),
    board_contact: str | None = board_contact_option(),
    json_out: bool = typer.Option(False, "--json", help="Print the result as JSON."),
    out: Path | None = typer.Option(None, "--out", help="Write the result JSON here."),
    report: Path | None = report_option(),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    instrument: str | None = instrument_option(),
    operator: str | None = operator_option(),
    note: str | None = note_option(),
) -> None:
    """Hand-eye calibration from (flange2base, target2cam) pose pairs."""
    from kinecal.calibration.handeye import calibrate_handeye

    check_paths({"PAIRS": pairs, "--robot-poses": robot_poses, "--target-poses": target_poses},
                {"--out": out, "--report": report})
    record = report_record(report, {"PAIRS": pairs, "--robot-poses": robot_poses,
                                    "--target-poses": target_poses}, instrument, operator, note)
    _check_pairs_mode(method, refine, pairs_mode)
    contact = parse_contact(board_contact)
    if camera_height is not None and contact is not None:
        raise InputError("give --camera-height or --board-contact, not both",
                         option="--board-contact")
    with warnings_scope(strict) as found:
        F, C, source, default_setup = read_pairs(pairs, robot_poses, target_poses,
                                                 robot_format, target_format, invert_robot,
                                                 invert_target)
        setup = setup or default_setup or "eye-in-hand"
        # the command line judges outlier stations whatever the refinement (a process
        # start costs more than the robust pass that --refine none needs for it)
        res = calibrate_handeye(F, C, setup=setup, method=method, refine=refine,
                                pairs=pairs_mode, seed=seed, robust=True,
                                camera_height=camera_height, board_contact=contact)
    if unit is not None and not unit.strip():
        raise InputError("expected a unit name such as mm or m", option="--unit")
    length_unit = unit or (_BUNDLED_UNIT.get(str(pairs).partition(":")[0]) if pairs
                           and not Path(pairs).exists() else None) or "input unit"
    result = with_warnings({"file": source, **res.to_dict(), "seed": seed,
                            "length_unit": length_unit}, found)
    write_outputs(out=out, result=result, report=report,
                  write_report=lambda path: _report(result, path, record),
                  quiet=quiet or json_out)
    if json_out:
        echo_json(result)
        return
    if quiet:
        return
    frame = "cam2flange" if setup == "eye-in-hand" else "cam2base"
    tframe = "target2base" if setup == "eye-in-hand" else "target2flange"
    label = (Path(source).name if pairs is not None
             else f"{Path(robot_poses).name} + {Path(target_poses).name}")
    u = length_unit
    lines = [
        f"{label}: {len(F)} stations, {setup}, method {res.method}, refine {refine}",
        *one_axis_lines(res.one_axis, u),
        f"X ({frame}; translation in {u}):",
        _format_matrix(res.X),
    ]
    if res.x_uncertainty is not None:
        xu = res.x_uncertainty
        lines.append(f"X uncertainty (1 sigma from the residuals, worst direction): rotation "
                     f"{xu.rotation_deg:.4g} deg, translation {xu.translation:.4g} {u}")
    lines += [
        f"target pose ({tframe}; translation in {u}):",
        _format_matrix(res.target),
        f"station residuals: rotation rms {res.rotation_rms_deg:.4g} deg, "
        f"translation rms {res.translation_rms:.4g} {u}",
        "outliers (0-based stations): "
        + (", ".join(str(i) for i in res.outliers) if res.outliers else "none"),
    ]
    if res.noise is not None:  # how the lm refinement weighed the stations
        lines.append(res.noise.describe(u))
    typer.echo("\n".join(lines))


def _report(result: dict, path: Path, record) -> None:
    from kinecal.report.html import handeye_report

    handeye_report(result, path, provenance=record)


@app.command("handeye-poses")
def handeye_poses(
    distance: float = typer.Option(..., "--distance", help="|Pc|: camera height above the "
                                   "target centre (length unit of the poses written)."),
    radius: float = typer.Option(..., "--radius", help="Circumradius r of the star polygon "
                                 "(length unit of the poses written)."),
    count: int = typer.Option(..., "--count", help="Number of poses N (>= 3)."),
    scheme: str = typer.Option("star", "--scheme", metavar=choices("star", "random"),
                               help="Star polygon (Li, Xiao, Lai and Hu 2024, sec. 3) or "
                               "random poses."),
    seed: int = seed_option("Random seed (scheme random; an integer >= 0)."),
    out: Path = typer.Option(..., "--out", help="Output CSV: camera_* (cam2target) and "
                             "target_* (target2cam) poses."),
) -> None:
    """Plan hand-eye camera poses: the star-polygon scheme of Li, Xiao, Lai and Hu (2024), or
    random."""
    from kinecal.calibration.handeye.poses import random_poses, star_polygon_poses
    from kinecal.io.csvtable import write_table
    from kinecal.io.handeye import pose_columns
    from kinecal.spatial import invert_transform, pq_from_transform

    check_paths({}, {"--out": out})
    if scheme not in ("star", "random"):
        raise InputError(f"unknown scheme {scheme!r}; expected star or random", option="--scheme")
    check_count(count, "--count", bytes_per_item=2048, what="poses", minimum=3)
    with np.errstate(all="ignore"):
        if scheme == "star":
            T = star_polygon_poses(distance, radius, count)
        else:
            T = random_poses(distance, radius, count, np.random.default_rng(seed))
    if not np.isfinite(T).all():
        raise InputError(f"distance {distance:g} and radius {radius:g} overflow the pose "
                         "arithmetic; expected lengths of a real setup", option="--radius")
    cols = {}
    for prefix, poses in (("camera", T), ("target", invert_transform(T))):
        pq = pq_from_transform(poses)
        cols.update({name: pq[:, k] for k, name in enumerate(pose_columns(prefix))})
    write_table(out, cols)
    typer.echo(f"{out}: {count} {scheme} poses (distance {distance:g}, radius {radius:g})")
