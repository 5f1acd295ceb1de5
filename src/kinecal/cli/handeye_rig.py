"""``kinecal handeye-images DIR ROBOT_POSES.csv --board SPEC --camera NAME[:I.yaml] ...``:
hand-eye calibration of several cameras (called by `kinecal.cli.handeye_images`; no
command is registered here). docs/rigs.md.

ROBOT_POSES has a ``camera`` column naming each image's camera beside ``image`` and the
flange pose. Every camera is on the flange (``--setup eye-in-hand``) or fixed
(``eye-to-hand``) and sees the one board; the result is X per camera, the board's pose and
every pair's camera-to-camera extrinsics with their uncertainty
(`kinecal.calibration.camera.rig_handeye`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import typer

from kinecal.cli._common import (
    check_paths,
    echo_json,
    progress,
    warnings_scope,
    with_warnings,
)
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

__all__ = ["handeye_rig_cli"]

#: the one-camera options a multi-camera hand-eye does not take
_ONE_CAMERA = {"intrinsics": "--intrinsics", "camera_height": "--camera-height",
               "board_contact": "--board-contact", "report": "--report",
               "robot_noise": "--robot-noise"}


def _cameras(values: list[str]) -> list[tuple[str, str | None]]:
    out = []
    for v in values:
        name, _, path = str(v).partition(":")
        if not name.strip():
            raise InputError(f"{v!r}: expected NAME[:intrinsics.yaml]", option="--camera")
        out.append((name.strip(), path.strip() or None))
    names = [n for n, _ in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"camera name(s) {', '.join(twice)} given twice", option="--camera")
    return out


def handeye_rig_cli(a: dict[str, Any], list_images: Callable, limits_option: Callable,
                    suffixes: tuple[str, ...]) -> None:
    """Run a multi-camera hand-eye calibration (module docstring); `a`: the
    ``handeye-images`` arguments, every one checked before any work; the image folder's
    listing, the ``--min-corners`` check and the image suffixes are that command's."""
    given = [opt for key, opt in _ONE_CAMERA.items() if a.get(key) not in (None, False)]
    if given:
        raise InputError("does not apply with several cameras (each camera's intrinsics: "
                         "--camera NAME:intrinsics.yaml)", option=given[0])
    cams = _cameras(a["camera"])
    inputs = {"IMAGES_DIR": a["images_dir"], "ROBOT_POSES": a["robot_poses"],
              **{f"--camera {n}": p for n, p in cams if p is not None}}
    check_paths(inputs, {"--out": a["out"]}, reads={"IMAGES_DIR": suffixes})
    if a["setup"] not in ("eye-in-hand", "eye-to-hand"):
        raise InputError(f"unknown setup {a['setup']!r}; expected eye-in-hand or eye-to-hand",
                         option="--setup")
    with warnings_scope(a["strict"]) as found:
        from kinecal.calibration.camera.rig_handeye import calibrate_rig_handeye
        from kinecal.io.csvtable import read_columns
        from kinecal.io.handeye import read_robot_poses
        from kinecal.vision.boards import parse_board
        from kinecal.vision.intrinsics import read_intrinsics
        from kinecal.vision.rig import Rig, RigBoard, RigCamera
        from kinecal.vision.rig_images import detect_rig

        board = parse_board(a["board"])
        limits = limits_option(a["min_corners"], board)
        in_hand = a["setup"] == "eye-in-hand"
        rig = Rig([RigCamera(n, "flange" if in_hand else "world",
                             read_intrinsics(Path(p)) if p else None, p) for n, p in cams],
                  [RigBoard("board", "world" if in_hand else "flange", board)])
        path = Path(a["robot_poses"])
        names, F = read_robot_poses(path)
        cells = read_columns(path, ["camera"]).get("camera")
        if cells is None:
            raise InputError(f"no camera column: with --camera each row names the camera of "
                             f"its image ({', '.join(rig.camera_names)})", file=path)
        camera = np.empty(len(names), np.intp)
        for r, cell in enumerate(cells, start=1):
            if cell not in rig.camera_names:
                raise InputError(f"column camera: {cell!r}, expected one of "
                                 f"{', '.join(rig.camera_names)}", file=path, row=r)
            camera[r - 1] = rig.camera_names.index(cell)
        files = list_images(Path(a["images_dir"]))
        by_name = {p.name: p for p in files}
        for row, name in enumerate(names, start=1):
            if name not in by_name:
                raise InputError(f"image {name!r} is not in {a['images_dir']}", file=path,
                                 row=row)
        extra = sorted(set(by_name) - set(names))
        if extra:
            raise InputError(f"{len(extra)} image(s) in {a['images_dir']} without a robot pose: "
                             f"{', '.join(extra[:5])}", file=path)
        missing = [n for k, n in enumerate(rig.camera_names) if not np.any(camera == k)]
        if missing:
            raise InputError(f"camera(s) {', '.join(missing)}: no row in {path.name}",
                             option="--camera")
        from kinecal.spatial import invert_transform
        from kinecal.vision.detection import orientation_ambiguous
        from kinecal.vision.turns import warn_symmetric

        if orientation_ambiguous(board):
            warn_symmetric(board)

        def relative(c: int, b: int, rows: list[int]) -> np.ndarray:
            """The board's link in the camera's: the flange poses (inverted in hand)."""
            return invert_transform(F[rows]) if in_hand else F[rows]

        with progress("detecting", len(names), a["quiet"] or a["json_out"]) as update:
            views, intr, skipped = detect_rig(rig, [by_name[n] for n in names], names, camera,
                                              np.zeros((len(names), 0)), [None] * len(names),
                                              limits, progress=update, relative=relative)
        keep = [names.index(n) for n in views.names]
        if skipped:
            from kinecal import diagnostics

            diagnostics.warn("station-skipped", f"{len(skipped)} of {len(names)} images "
                             f"skipped (e.g. {skipped[0]['image']}: {skipped[0]['reason']})")
        refine = a["refine_intrinsics"]
        flags = [(c.intrinsics is None) if refine is None else bool(refine)
                 for c in rig.cameras]
        res = calibrate_rig_handeye(views, F[keep], rig.camera_names, [i.K for i in intr],
                                    [i.dist for i in intr], setup=a["setup"],
                                    refine_intrinsics=flags, board_spec=board.spec,
                                    method=a["method"])
        res.extra["skipped"] = skipped
        res.warnings = list(found)
        result = with_warnings({"images_dir": str(a["images_dir"]), "robot_poses": str(path),
                                **res.to_dict()}, found)
        write_outputs(out=a["out"], result=result, quiet=a["quiet"] or a["json_out"])
    if a["json_out"]:
        echo_json(result)
    elif not a["quiet"]:
        typer.echo(res.summary())
