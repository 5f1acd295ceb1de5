"""``kinecal calibrate MODEL STATIONS.csv --images DIR --board SPEC``: the arm from camera
images (called by `kinecal.cli.calibrate.calibrate` when ``--images`` is given; no command
is registered here)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from kinecal.cli._common import (
    check_paths,
    echo_json,
    progress,
    report_record,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._options import check_unit, load_model_arg
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

__all__ = ["calibrate_images"]

#: options of ``calibrate`` that measured positions use and images do not
_POSITION_ONLY = {"error_model": "--error-model", "harmonics": "--harmonics",
                  "folds": "--folds", "rotation_weight": "--rotation-weight",
                  "sigma": "--sigma", "maxiter": "--maxiter", "target": "--target",
                  "fixture": "--fixture", "orientation_format": "--orientation-format",
                  "station_per_file": "--station-per-file",
                  "validate_register": "--validate-register"}


def _one(value: Any, option: str) -> str | None:
    """The one file of an argument that may list several (``calibrate A.csv B.csv``)."""
    if value is None or isinstance(value, str | Path):
        return value
    files = list(value)
    if len(files) > 1:
        raise InputError(f"--images takes one stations file, got {len(files)}: "
                         f"{', '.join(files)}", option=option)
    return files[0] if files else None


def _match(folder: Path, path: Path, names: list[str], by_name: dict[str, Path]) -> None:
    for row, name in enumerate(names, start=1):
        if name not in by_name:
            raise InputError(f"image {name!r} is not in {folder}: joints without an image",
                             file=path, row=row)


def _validation(model: Any, path: Path, folder: Path, images: Path, by_name: dict[str, Path],
                names: list[str], listed: set[str], angle_unit: str | None = None
                ) -> tuple[Any, set[str]]:
    """The held-out stations of ``--validate`` (their images in `folder`: ``--images`` or
    ``--validate-images``) and the image names of ``--images`` now accounted for. A
    validation image that is also a calibration image is refused (same file)."""
    from kinecal.cli.handeye_images import list_images
    from kinecal.io.stations import read_stations

    vnames, vq = read_stations(path, model, angle_unit=angle_unit)
    same = folder.resolve() == images.resolve()
    vby = by_name if same else {p.name: p for p in list_images(folder)}
    _match(folder, path, vnames, vby)
    used = {by_name[n].resolve() for n in names}
    both = [n for n in vnames if vby[n].resolve() in used]
    if both:
        raise InputError(f"{len(both)} image(s) also in the calibration stations, e.g. "
                         f"{both[0]!r}: validation stations must be held out (images of "
                         "another folder: --validate-images)", file=path)
    if not same:
        extra = sorted(set(vby) - set(vnames))
        if extra:
            raise InputError(f"{len(extra)} image(s) in {folder} without joints (no row in "
                             f"{path.name}): {', '.join(extra[:5])}"
                             f"{', ...' if len(extra) > 5 else ''}", file=path)
        return ([vby[n] for n in vnames], vq, vnames), listed
    return ([vby[n] for n in vnames], vq, vnames), listed | set(vnames)


def calibrate_images(args: dict[str, Any]) -> None:
    """Run the calibration from images (see `kinecal.vision.arm_images`) and write the
    outputs; `args` are ``calibrate``'s arguments. Every argument is checked before any
    work."""
    from kinecal.cli._serial_common import free_option

    given = [opt for key, opt in _POSITION_ONLY.items()
             if args.get(key) not in (None, [], False)]
    if given:
        raise InputError("applies to measured positions, not to --images", option=given[0])
    data, validate = _one(args["data"], "STATIONS"), _one(args["validate"], "--validate")
    _run(model=args["model"], base_link=args["base_link"], tip_link=args["tip_link"],
         data=data, images=args["images"], board=args["board"],
         intrinsics=args["intrinsics"], setup=args["setup"], method=args["method"],
         validate=validate, free=free_option(args["free"]), loss=args["loss"],
         out=args["out"], model_out=args["model_out"], report=args["report"],
         json_out=args["json_out"], quiet=args["quiet"], strict=args["strict"],
         min_corners=args["min_corners"], unit=args["unit"],
         validate_images=args["validate_images"], angle_unit=args.get("angle_unit"),
         record=(args["instrument"], args["operator"], args["note"]))


def _run(*, model: str, base_link: str | None, tip_link: str | None, data: str,
         images: Path, board: str | None, intrinsics: Path | None, setup: str, method: str,
         validate: str | None, free: Any, loss: str, out: Path | None,
         model_out: Path | None, report: Path | None, json_out: bool, quiet: bool,
         strict: bool, min_corners: int | None = None, unit: str = "auto",
         validate_images: Path | None = None, angle_unit: str | None = None,
         record: tuple[str | None, str | None, str | None] = (None, None, None)) -> None:
    from kinecal.cli.handeye_images import IMAGE_SUFFIXES, limits_option, list_images

    if method != "lm":
        raise InputError(f"--images calibrates by Levenberg-Marquardt on the pixels; got "
                         f"{method!r}", option="--method")
    if board is None:
        raise InputError("--images needs the board: e.g. --board chessboard:9x6:25",
                         option="--board")
    if setup not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {setup!r}; expected eye-in-hand or eye-to-hand",
                         option="--setup")
    shown = check_unit(unit)
    if validate_images is not None and validate is None:
        raise InputError("applies to --validate only (the folder of its images)",
                         option="--validate-images")
    inputs = {"MODEL": model, "STATIONS": data, "--images": images,
              "--intrinsics": intrinsics, "--validate": validate,
              "--validate-images": validate_images}
    folders = {"--images": IMAGE_SUFFIXES, "--validate-images": IMAGE_SUFFIXES}
    check_paths(inputs, {"--out": out, "--model-out": model_out, "--report": report},
                reads=folders)
    prov = report_record(report, inputs, *record, suffixes=folders)
    if model_out is not None:
        from kinecal.io.models import check_model_file_name

        check_model_file_name(model_out, "--model-out")
    with warnings_scope(strict) as found:
        from kinecal.io.stations import read_stations
        from kinecal.vision.arm_images import calibrate_arm_images
        from kinecal.vision.boards import parse_board
        from kinecal.vision.intrinsics import read_intrinsics

        the_board = parse_board(board)
        limits = limits_option(min_corners, the_board)
        m = load_model_arg(model, base_link, tip_link)
        names, q = read_stations(Path(data), m, angle_unit=angle_unit)
        files = list_images(images)
        by_name = {p.name: p for p in files}
        _match(images, Path(data), names, by_name)
        val, listed = None, set(names)
        if validate is not None:
            val, listed = _validation(m, Path(validate), validate_images or images, images,
                                      by_name, names, listed, angle_unit)
        unlisted = sorted(set(by_name) - listed)
        if unlisted:
            raise InputError(f"{len(unlisted)} image(s) in {images} without joints (no row in "
                             f"{Path(data).name}{' or --validate' if validate else ''}): "
                             f"{', '.join(unlisted[:5])}{', ...' if len(unlisted) > 5 else ''}",
                             file=Path(data))
        intr = read_intrinsics(intrinsics) if intrinsics is not None else None
        with progress("detecting", len(names), quiet or json_out) as update:
            res = calibrate_arm_images(m, [by_name[n] for n in names], q, the_board,
                                       names=names, intrinsics=intr, setup=setup, free=free,
                                       loss=loss, validate=val, progress=update,
                                       limits=limits)
        res.warnings = list(found)
        result = with_warnings({"images_dir": str(images), "stations": str(data),
                                **res.to_dict()}, found)
        write_outputs(out=out, result=result, model_out=model_out, save_model=res.save_model,
                      report=report, write_report=lambda path: _report(res, path, prov),
                      quiet=quiet or json_out)
    if json_out:
        echo_json(result)
    elif not quiet:
        typer.echo(res.summary(shown))


def _report(res: Any, path: Path, prov: Any) -> None:
    from kinecal.report.arm_images import arm_images_report

    arm_images_report(res, path, provenance=prov)
