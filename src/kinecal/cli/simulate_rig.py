"""``kinecal simulate MODEL --images DIR --camera NAME:LINK[:I.yaml] ... --board
NAME:LINK:SPEC ... --poses N --out STATIONS.csv``: rendered images of a camera rig on a
perturbed arm or robot system (called by `kinecal.cli.simulate.simulate`; no command is
registered here). docs/rigs.md.

Each camera renders with its own intrinsics (its file, else the default 800 x 600 px
camera of `kinecal.cli.simulate_images`); ``--camera-out DIR`` writes each camera's
intrinsics as ``DIR/NAME.yaml``, ``--truth-out`` the true errors and mounts.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import typer

from kinecal._limits import check_count, check_finite
from kinecal.cli._common import check_paths, status, warnings_scope
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

__all__ = ["is_rig_simulation", "simulate_rig"]

#: options of ``simulate`` that measured positions use and a rig's images do not
_POSITION_ONLY = {"orientation": "--orientation", "angle_noise": "--angle-noise",
                  "pivot": "--pivot", "point": "--point", "plane": "--plane",
                  "length": "--length", "radius": "--radius", "groups": "--groups",
                  "sigma_column": "--sigma-column", "tip": "--tip", "carrier": "--carrier",
                  "intrinsics": "--intrinsics"}


def is_rig_simulation(camera: list[str] | None, board: list[str] | None, system: bool) -> bool:
    """Whether ``simulate --images`` renders a rig (cameras named, boards mounted, or a
    robot system)."""
    from kinecal.vision.rig import is_mounted_board

    return bool(camera) or any(is_mounted_board(b) for b in board or []) or system


def simulate_rig(a: dict[str, Any]) -> None:
    """Render the rig's images and write them, STATIONS.csv, the truth and the cameras'
    files (`a`: ``simulate``'s arguments, all checked before any work)."""
    from kinecal.cli.simulate_images import DEFAULT_CAMERA, MAX_BLUR, MAX_NOISE, home_joints

    given = [opt for key, opt in _POSITION_ONLY.items() if a.get(key) not in (None, False, [])]
    if given:
        raise InputError("does not apply to a rig's images (each camera's intrinsics: "
                         "--camera NAME:LINK:camera.yaml)", option=given[0])
    if a.get("kind", "tracker") != "tracker" or a.get("joints") is not None:
        raise InputError("--images renders a rig's stations: --poses N only",
                         option="--kind" if a.get("joints") is None else "--joints")
    if a["setup"] != "eye-in-hand":
        raise InputError("a rig's cameras and boards name their links", option="--setup")
    if not a["camera"] or not a["board"]:
        raise InputError("a rig needs --camera NAME:LINK[:intrinsics.yaml] and --board "
                         "NAME:LINK:SPEC (each repeatable)", option="--camera")
    errors, out = a["errors"], a["out"]
    inputs = {"MODEL": a["model"],
              "--errors": None if errors in ("zero", "random") else errors,
              **{f"--camera {c}": c.split(":", 2)[2] for c in a["camera"]
                 if c.count(":") >= 2}}
    check_paths(inputs, {"--out": out, "--truth-out": a["truth_out"]})
    for key, most in (("noise", MAX_NOISE), ("blur", MAX_BLUR)):
        if check_finite(a[key], f"--{key}") > most:
            raise InputError(f"{a[key]:g}: expected at most {most:g}", option=f"--{key}")
    if a["poses"] is None:
        raise InputError("expected --poses N (stations)", option="--poses")
    n = check_count(a["poses"], "--poses", bytes_per_item=2_000_000 * len(a["camera"]))
    with warnings_scope(a["strict"]):
        from kinecal.calibration.serial.simulate import read_truth
        from kinecal.cli._options import load_model_arg
        from kinecal.cli.systems import is_system_arg, load_system_arg
        from kinecal.vision.imaging import ImageConditions
        from kinecal.vision.rig import parse_rig
        from kinecal.vision.rig_files import (
            write_rig_cameras,
            write_rig_images,
            write_rig_stations_of,
            write_rig_truth,
        )
        from kinecal.vision.rig_scene import render_rig_stations

        rig = parse_rig(a["camera"], a["board"])
        if is_system_arg(a["model"], a["base_link"], a["tip_link"]):
            m = load_system_arg(a["model"], a["base_link"], a["tip_link"])
        else:
            m = load_model_arg(a["model"], a["base_link"], a["tip_link"])
        cams, boards = rig.mounts(m)
        err = errors if errors in ("zero", "random") else read_truth(Path(errors), m) - m.nominal
        cam = []
        for c in rig.cameras:
            if c.intrinsics is None:
                cam.append((np.asarray(DEFAULT_CAMERA["K"]), np.asarray(DEFAULT_CAMERA["dist"]),
                            DEFAULT_CAMERA["size"]))
            elif not c.intrinsics.size:
                raise InputError("the camera file gives no image size", file=c.intrinsics_file)
            else:
                cam.append((c.intrinsics.K, c.intrinsics.dist, tuple(c.intrinsics.size)))
        with status(f"rendering {n} stations of {len(cams)} cameras", a["quiet"]):
            scene = render_rig_stations(
                m, cams, [(mb, b.board) for mb, b in zip(boards, rig.boards, strict=True)],
                cam, n, errors=err, q_home=home_joints(a["home"], m), seed=a["seed"],
                conditions=ImageConditions(blur=a["blur"], noise=a["noise"]), supersample=2)
        write_outputs(more=[(a["images"], lambda path: write_rig_images(scene, path)),
                            (out, lambda path: write_rig_stations_of(scene, path)),
                            (a["truth_out"], lambda path: write_rig_truth(scene, path)),
                            (a["camera_out"], lambda path: write_rig_cameras(scene, path))],
                      quiet=a["quiet"])
    if not a["quiet"]:
        per = ", ".join(f"{c.name} {int(np.sum(scene.camera == k))}"
                        for k, c in enumerate(cams))
        typer.echo(f"wrote {len(scene.names)} images of {n} stations ({per}) to {a['images']} "
                   f"and their joints to {out}", err=True)
