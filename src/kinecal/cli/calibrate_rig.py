"""``kinecal calibrate MODEL STATIONS.csv [MORE.csv ...] --images DIR --camera NAME:LINK[:I.yaml]
... --board NAME:LINK:SPEC ...``: a model and its camera rig from images, mixed with
tracker and gauge files (called by `kinecal.cli.calibrate.calibrate`; no command is
registered here). docs/rigs.md.

The one-camera forms (``--board SPEC [--intrinsics I.yaml] [--setup ...]``,
docs/arm-from-images.md) come here too when they are mixed with other files or calibrate a
robot system: the camera then hangs from the flange (eye-in-hand) or the world
(eye-to-hand) and the board from the other.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import typer

from kinecal.cli._common import (
    check_paths,
    echo_json,
    progress,
    report_record,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

__all__ = ["calibrate_rig_cli", "is_rig_call", "one_board"]

#: options of ``calibrate`` that a rig does not use
_NOT_FOR_RIGS = {"error_model": "--error-model", "harmonics": "--harmonics",
                 "folds": "--folds", "maxiter": "--maxiter", "target": "--target",
                 "fixture": "--fixture", "rotation_weight": "--rotation-weight"}


def is_rig_call(camera: list[str] | None, board: list[str] | None, data: list[str],
                system: bool) -> bool:
    """Whether ``calibrate --images`` is a rig's (cameras named, boards mounted, several
    data files, or a robot system) rather than the one-camera form."""
    from kinecal.vision.rig import is_mounted_board

    return bool(camera) or any(is_mounted_board(b) for b in board or []) or \
        len(data) > 1 or system


def one_board(board: list[str] | None) -> str | None:
    """The one ``--board SPEC`` of the one-camera forms."""
    board = list(board or [])
    if len(board) > 1:
        raise InputError(f"{len(board)} boards: several boards are a rig's (--board "
                         "NAME:LINK:SPEC with --camera NAME:LINK; docs/rigs.md)",
                         option="--board")
    return board[0] if board else None


def _rig_of(a: dict[str, Any]) -> tuple[list[str], list[str]]:
    """The ``--camera`` and ``--board`` values, the one-camera form turned into a rig's."""
    from kinecal.vision.rig import is_mounted_board

    cams, boards = list(a["camera"] or []), list(a["board"] or [])
    if cams or any(is_mounted_board(b) for b in boards):
        for key, opt in (("intrinsics", "--intrinsics"),):
            if a.get(key) is not None:
                raise InputError("a rig's cameras carry their intrinsics: --camera "
                                 "NAME:LINK:intrinsics.yaml", option=opt)
        if a["setup"] != "eye-in-hand":
            raise InputError("a rig's cameras and boards name their links (--camera NAME:LINK, "
                             "--board NAME:LINK:SPEC)", option="--setup")
        return cams, boards
    spec = one_board(boards)
    if spec is None:
        raise InputError("--images needs the board: e.g. --board chessboard:9x6:25 (or a "
                         "rig's --board NAME:LINK:SPEC)", option="--board")
    if a["setup"] not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {a['setup']!r}; expected eye-in-hand or eye-to-hand",
                         option="--setup")
    in_hand = a["setup"] == "eye-in-hand"
    intr = f":{a['intrinsics']}" if a.get("intrinsics") is not None else ""
    return ([f"camera:{'flange' if in_hand else 'world'}{intr}"],
            [f"board:{'world' if in_hand else 'flange'}:{spec}"])


def _split(files: list[str]) -> tuple[str, list[str]]:
    """The STATIONS.csv (the file with an ``image`` column) and the other data files."""
    from kinecal.cli._common import resolve_data_path
    from kinecal.io.poses import first_csv_row

    stations = [f for f in files if "image" in first_csv_row(resolve_data_path(f))]
    if len(stations) != 1:
        raise InputError(f"{len(stations)} files with an image column among DATA: expected "
                         "one STATIONS.csv (image,camera[,board],<joints>) beside tracker and "
                         "gauge files", option="DATA")
    return stations[0], [f for f in files if f != stations[0]]


def calibrate_rig_cli(a: dict[str, Any]) -> None:
    """Run a rig's calibration (module docstring); `a`: ``calibrate``'s arguments, every
    one checked before any work."""
    given = [opt for key, opt in _NOT_FOR_RIGS.items() if a.get(key) not in (None, [])]
    if given:
        raise InputError("does not apply to --images (docs/rigs.md)", option=given[0])
    if a["method"] != "lm":
        raise InputError(f"--images calibrates by Levenberg-Marquardt on the pixels; got "
                         f"{a['method']!r}", option="--method")
    cams, boards = _rig_of(a)
    stations, others = _split(list(a["data"]))
    validate = list(a["validate"] or [])
    if len(validate) > 1:
        raise InputError(f"--validate takes one held-out STATIONS.csv with --images, got "
                         f"{len(validate)}", option="--validate")
    from kinecal.cli.handeye_images import IMAGE_SUFFIXES

    inputs = {"MODEL": a["model"], "STATIONS": stations, "--images": a["images"],
              "--validate-images": a.get("validate_images"),
              **{f"DATA {f}": f for f in others},
              **{f"--validate {v}": v for v in validate},
              **{f"--camera {c}": c.split(":", 2)[2] for c in cams if c.count(":") >= 2}}
    folders = {"--images": IMAGE_SUFFIXES, "--validate-images": IMAGE_SUFFIXES}
    check_paths(inputs, {"--out": a["out"], "--model-out": a["model_out"],
                         "--report": a["report"]}, reads=folders)
    prov = report_record(a["report"], inputs, a["instrument"], a["operator"], a["note"],
                         suffixes=folders)
    with warnings_scope(a["strict"]) as found:
        res = _run(a, cams, boards, stations, others, validate[0] if validate else None)
        res.warnings = list(found)
        result = with_warnings({"images_dir": str(a["images"]), "stations": str(stations),
                                **res.to_dict()}, found)
        write_outputs(out=a["out"], result=result, model_out=a["model_out"],
                      save_model=res.fit.save_model, report=a["report"],
                      write_report=lambda path: _report(res, path, prov),
                      quiet=a["quiet"] or a["json_out"])
    if a["json_out"]:
        echo_json(result)
    elif not a["quiet"]:
        typer.echo(res.summary())


def _run(a: dict[str, Any], cams: list[str], boards: list[str], stations: str,
         others: list[str], validate: str | None):
    from kinecal.cli._options import load_model_arg
    from kinecal.cli.calibrate_kinds import _read_all, parse_sigma
    from kinecal.cli.handeye_images import limits_option, list_images
    from kinecal.cli.systems import is_system_arg, load_system_arg
    from kinecal.io.rig_stations import read_rig_stations
    from kinecal.vision.rig import parse_rig
    from kinecal.vision.rig_images import (
        calibrate_rig_images,
        complete_joints,
        searched_boards,
    )

    rig = parse_rig(cams, boards)
    system = is_system_arg(a["model"], a["base_link"], a["tip_link"])
    if system:
        if a["model_out"] is not None:
            raise InputError("a robot system is written with kinecal export (docs/systems.md)",
                             option="--model-out")
        m = load_system_arg(a["model"], a["base_link"], a["tip_link"])
    else:
        m = load_model_arg(a["model"], a["base_link"], a["tip_link"])
    rig.mounts(m)  # every link known before any image is read
    limits = limits_option(a["min_corners"], rig.boards[0].board) \
        if a["min_corners"] is not None else None
    unit = a.get("angle_unit")
    st = read_rig_stations(Path(stations), m, rig.camera_names, rig.board_names,
                           angle_unit=unit)
    search = searched_boards(rig, st.camera, st.board)  # boards one image cannot tell apart
    unseen = [b for k, b in enumerate(rig.board_names) if not any(k in s for s in search)]
    if unseen:
        raise InputError(f"board(s) {', '.join(unseen)}: no image is searched for them (name "
                         "the board of an image in the STATIONS.csv board column)",
                         option="--board")
    silent = [c for k, c in enumerate(rig.camera_names) if not np.any(st.camera == k)]
    if silent:
        raise InputError(f"camera(s) {', '.join(silent)}: no image of theirs in "
                         f"{Path(stations).name} (every --camera needs images)",
                         option="--camera")
    folder = Path(a["images"])
    by_name = {p.name: p for p in list_images(folder)}
    _match(folder, Path(stations), st.names, by_name)
    val, listed = None, set(st.names)
    vfolder = a.get("validate_images")
    if vfolder is not None and validate is None:
        raise InputError("applies to --validate only (the folder of its images)",
                         option="--validate-images")
    if validate is not None:
        vs = read_rig_stations(Path(validate), m, rig.camera_names, rig.board_names,
                               angle_unit=unit)
        vby = by_name if vfolder is None else {p.name: p for p in list_images(Path(vfolder))}
        _match(Path(vfolder or folder), Path(validate), vs.names, vby)
        both = sorted({vby[n].resolve() for n in vs.names} & {by_name[n].resolve()
                                                              for n in st.names})
        if both:
            raise InputError(f"{len(both)} image(s) also in the calibration stations, e.g. "
                             f"{both[0].name!r}: validation images must be held out (images "
                             "of another folder: --validate-images)", file=Path(validate))
        val = ([vby[n] for n in vs.names], vs.names, vs.camera,
               complete_joints(m, rig, vs.camera, vs.board, vs.q, vs.names), vs.board)
        if vfolder is None:
            listed |= set(vs.names)
        else:
            _all_listed(Path(vfolder), vby, set(vs.names), Path(validate))
    _all_listed(folder, by_name, listed, Path(stations),
                " or --validate" if validate and vfolder is None else "")
    q = complete_joints(m, rig, st.camera, st.board, st.q, st.names)
    if system:
        from kinecal.cli.systems import _read

        sets = _read(m, others, "DATA", a.get("tip"), unit)
    else:
        sets = _read_all(m, others, "DATA", None, unit) if others else []
    stated = parse_sigma(a["sigma"], others) if others else None
    with progress("detecting", len(st.names), a["quiet"] or a["json_out"]) as update:
        return calibrate_rig_images(m, rig, [by_name[n] for n in st.names], st.names,
                                    st.camera, q, st.board, free=a["free"], loss=a["loss"],
                                    validate=val, limits=limits, progress=update,
                                    others=sets, sigma=stated)


def _report(res: Any, path: Path, prov: Any) -> None:
    """The calibration's report (parameters, errors, every set's unknowns with the mounts)."""
    from kinecal.report.html import calibration_report

    calibration_report(res.fit, path, provenance=prov)


def _all_listed(folder: Path, by_name: dict[str, Path], listed: set[str], path: Path,
                more: str = "") -> None:
    """Every image of `folder` has a row (an image without joints is a mistake)."""
    unlisted = sorted(set(by_name) - listed)
    if unlisted:
        raise InputError(f"{len(unlisted)} image(s) in {folder} without joints (no row in "
                         f"{path.name}{more}): {', '.join(unlisted[:5])}"
                         f"{', ...' if len(unlisted) > 5 else ''}", file=path)


def _match(folder: Path, path: Path, names: list[str], by_name: dict[str, Path]) -> None:
    for row, name in enumerate(names, start=1):
        if name not in by_name:
            raise InputError(f"image {name!r} is not in {folder}: joints without an image",
                             file=path, row=row)
