"""``kinecal handeye-images``: hand-eye calibration from board images and robot poses."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import typer

from kinecal.cli._app import app
from kinecal.cli._common import (
    check_paths,
    echo_json,
    progress,
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
    strict_option,
)
from kinecal.cli._outputs import write_outputs
from kinecal.cli.handeye import (
    board_contact_option,
    camera_height_option,
    one_axis_lines,
    parse_contact,
)
from kinecal.errors import InputError

#: image file types listed from IMAGES_DIR
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp")


def list_images(folder: Path) -> list[Path]:
    """Image files directly inside `folder`, sorted by name; `InputError` when none."""
    if not folder.exists():
        raise InputError("folder not found", file=folder)
    if not folder.is_dir():
        raise InputError("is not a folder; expected the folder holding the images", file=folder)
    files = sorted(p for p in folder.iterdir()
                   if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise InputError(f"no images in the folder (expected {', '.join(IMAGE_SUFFIXES)} "
                         "files)", file=folder)
    return files


def _parse_robot_noise(text: str | None) -> tuple[float, float] | str | None:
    """``--robot-noise``: ``auto`` (default: estimated), ``exact`` or ``ROT_DEG,TRANS``."""
    if text is None or text.strip() == "auto":
        return "auto"
    if text.strip() == "exact":
        return None
    try:
        rot_deg, trans = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"{text!r}: expected auto, exact or ROT_DEG,TRANS (e.g. 0.02,0.1)",
                         option="--robot-noise") from None
    if not (rot_deg > 0 and trans > 0 and np.isfinite(rot_deg) and np.isfinite(trans)):
        raise InputError(f"{text!r}: expected two positive numbers", option="--robot-noise")
    return float(np.radians(rot_deg)), trans


def limits_option(min_corners: int | None, board: Any) -> Any:
    """QualityLimits with ``--min-corners`` checked against the board (4 .. its corners);
    refused for boards found whole or not at all (chessboards, circle grids)."""
    from kinecal.vision.boards import Charuco
    from kinecal.vision.detection import QualityLimits

    if min_corners is None:
        return QualityLimits()
    if not isinstance(board, Charuco):
        raise InputError(f"applies to ChArUco boards, which may be seen in part; the board "
                         f"{board.spec} is found whole ({board.n_corners} corners) or not "
                         "at all", option="--min-corners")
    if not 4 <= min_corners <= board.n_corners:
        raise InputError(f"{min_corners}: expected 4 to {board.n_corners} (the corners of "
                         f"{board.spec}; a board pose needs at least 4)",
                         option="--min-corners")
    return QualityLimits(min_corners=min_corners)


def _fmt_matrix(T: np.ndarray) -> str:
    return "\n".join("  [" + ", ".join(f"{v:12.6f}" for v in row) + "]" for row in T)


@app.command("handeye-images")
def handeye_images(
    images_dir: Path = typer.Argument(..., help="Folder with one board image per station."),
    robot_poses: Path = typer.Argument(..., help="CSV: image, flange_x..flange_qz "
                                       "(flange2base, board length unit) per image."),
    board: str = typer.Option(..., "--board", help="chessboard:COLSxROWS:SQUARE (inner "
                              "corners), charuco:COLSxROWS:SQUARE:MARKER:DICT (squares), "
                              "acircles:COLSxROWS:SPACING, circles:COLSxROWS:PITCH[:DIAMETER] "
                              "or modcircles:COLSxROWS:PITCH[:DIAMETER] (industrial_"
                              "calibration's modified circle grid)."),
    intrinsics: Path | None = typer.Option(None, "--intrinsics", help="Camera: ROS "
                                           "camera_calibration YAML, OpenCV FileStorage or "
                                           "JSON (default: estimated from the images)."),
    setup: str = typer.Option("eye-in-hand", "--setup",
                              metavar=choices("eye-in-hand", "eye-to-hand"),
                              help="Camera on the flange or fixed."),
    method: str = typer.Option("park", "--method", metavar=choices(
        "tsai", "park", "horaud", "andreff", "daniilidis", "shah", "li"),
        help="Closed form seeding the refinement."),
    refine_intrinsics: bool | None = typer.Option(
        None, "--refine-intrinsics/--fix-intrinsics", help="Refine the intrinsics jointly "
        "with X (default: when estimated from the images, not when given)."),
    robot_noise: str | None = typer.Option(
        None, "--robot-noise", metavar="auto|exact|ROT_DEG,TRANS",
        help="Robot pose errors: auto (default) estimates their std from the stations' "
        "consistency and models them when they matter; exact trusts the poses; or the std "
        "(deg, board length unit, e.g. 0.02,0.1)."),
    min_corners: int | None = typer.Option(None, "--min-corners", help="Fewest corners an "
                                           "image must show (ChArUco boards, seen in part; "
                                           "default 60 % of the board's corners, at least "
                                           "6). Grid boards are found whole or not at all."),
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
    camera: list[str] | None = typer.Option(
        None, "--camera", help="Several cameras: NAME[:intrinsics.yaml] (repeatable); "
        "ROBOT_POSES then has a camera column (docs/rigs.md)."),
) -> None:
    """Hand-eye calibration from images of a calibration board and the robot poses."""
    if camera:  # several cameras: X per camera and camera-to-camera, its own module
        from kinecal.cli.handeye_rig import handeye_rig_cli

        return handeye_rig_cli(dict(locals()), list_images, limits_option, IMAGE_SUFFIXES)
    check_paths({"IMAGES_DIR": images_dir, "ROBOT_POSES": robot_poses,
                 "--intrinsics": intrinsics}, {"--out": out, "--report": report},
                reads={"IMAGES_DIR": IMAGE_SUFFIXES})
    record = report_record(report, {"IMAGES_DIR": images_dir, "ROBOT_POSES": robot_poses,
                                    "--intrinsics": intrinsics}, instrument, operator, note,
                           suffixes={"IMAGES_DIR": IMAGE_SUFFIXES})
    from kinecal.calibration.handeye import METHODS, SETUPS
    from kinecal.io.handeye import read_robot_poses

    if setup not in SETUPS:
        raise InputError(f"unknown setup {setup!r}; expected {' or '.join(SETUPS)}",
                         option="--setup")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}",
                         option="--method")
    noise = _parse_robot_noise(robot_noise)
    contact = parse_contact(board_contact)
    if camera_height is not None and contact is not None:
        raise InputError("give --camera-height or --board-contact, not both",
                         option="--board-contact")
    with warnings_scope(strict) as found:
        from kinecal.vision.boards import parse_board
        from kinecal.vision.intrinsics import read_intrinsics
        from kinecal.vision.pipeline import calibrate_handeye_images

        the_board = parse_board(board)
        limits = limits_option(min_corners, the_board)
        files = list_images(images_dir)
        names, F = read_robot_poses(robot_poses)
        by_name = {p.name: p for p in files}
        for row, name in enumerate(names, start=1):
            if name not in by_name:
                raise InputError(f"image {name!r} is not in {images_dir}", file=robot_poses,
                                 row=row)
        if len(files) != len(names):
            extra = sorted(set(by_name) - set(names))
            raise InputError(f"{len(files)} images in {images_dir} but {len(names)} robot "
                             f"poses: expected one row per image (not in the CSV: "
                             f"{', '.join(extra[:5])}{', ...' if len(extra) > 5 else ''})",
                             file=robot_poses)
        intr = read_intrinsics(intrinsics) if intrinsics is not None else None
        with progress("detecting", len(names), quiet) as update:
            res = calibrate_handeye_images([by_name[n] for n in names], F, the_board,
                                           names=names, intrinsics=intr, setup=setup,
                                           method=method, refine_intrinsics=refine_intrinsics,
                                           robot_noise=noise, limits=limits, progress=update,
                                           camera_height=camera_height, board_contact=contact)
        result = with_warnings({"images_dir": str(images_dir),
                                "robot_poses": str(robot_poses), **res.to_dict()}, found)
        write_outputs(out=out, result=result, report=report,
                      write_report=lambda path: _report(res, path, [by_name[n] for n in names],
                                                        result, record),
                      quiet=quiet or json_out)
    if json_out:
        echo_json(result)
        return
    if quiet:
        return
    typer.echo(_summary(res))


def _report(res: Any, path: Path, images: list, result: dict, record: Any) -> None:
    from kinecal.report.handeye_images import handeye_images_report

    handeye_images_report(res, path, images=images, result_dict=result, provenance=record)


def _summary(res: Any) -> str:
    xr, xt = res.X_std
    frame = "cam2flange" if res.setup == "eye-in-hand" else "cam2base"
    tframe = "target2base" if res.setup == "eye-in-hand" else "target2flange"
    intr = res.intrinsics
    lines = [
        f"{len(res.records)} images, {len(res.used)} used, {len(res.rejected)} rejected, "
        f"{len(res.outliers)} outlier(s); {res.setup}, board {res.board.spec}",
        *one_axis_lines(res.one_axis, "mm"),
        f"X ({frame}; translation in the board unit, mm):",
        _fmt_matrix(res.X),
        "X std (1 sigma): rotation " + ", ".join(f"{v:.4f}" for v in xr) + " deg, translation "
        + ", ".join(f"{v:.4f}" for v in xt) + " mm",
        f"board pose ({tframe}, mm):",
        _fmt_matrix(res.target),
        res.refinement.robot_noise.describe("mm") if res.refinement.robot_noise is not None
        else "",
        f"reprojection RMS {res.refinement.rms_px:.3f} px (corner sigma "
        f"{res.refinement.sigma_px:.3f} px)",
        intr.describe(res.intrinsics_refined),
    ]
    for r in res.records:
        if r.status != "used":
            lines.append(f"  {r.status}: {r.name}: {r.reason}")
    return "\n".join(lines)
