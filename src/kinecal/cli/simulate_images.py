"""``kinecal simulate MODEL --images DIR --board SPEC --poses N --out STATIONS.csv``: rendered
stations of a perturbed arm (called by `kinecal.cli.simulate.simulate` when ``--images`` is
given; no command is registered here)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import typer

from kinecal._limits import check_count, check_finite
from kinecal.cli._common import check_paths, status, warnings_scope
from kinecal.cli._options import load_model_arg
from kinecal.cli._outputs import write_outputs
from kinecal.errors import InputError

__all__ = ["DEFAULT_CAMERA", "home_joints", "simulate_images"]

#: largest --noise (grey levels: beyond the 0-255 range every pixel is noise) and --blur
#: (px sigma: a Gaussian kernel of 6 sigma; 1e4 px ran for minutes, 1e308 crashed OpenCV)
MAX_NOISE, MAX_BLUR = 255.0, 100.0

#: the camera of a simulation without --intrinsics: 800 x 600 px, f 900 px, mild distortion
DEFAULT_CAMERA = {"K": [[900.0, 0.0, 399.5], [0.0, 900.0, 299.5], [0.0, 0.0, 1.0]],
                  "dist": [-0.15, 0.06, 0.0005, -0.0003, 0.0], "size": (800, 600)}


def home_joints(text: str | None, model: Any) -> np.ndarray | None:
    """``--home q1,..,qn`` in the model's units as internal joint values (None: not given)."""
    if text is None:
        return None
    try:
        v = np.array([float(t) for t in text.split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (model.n_joints,) or not np.isfinite(v).all():
        raise InputError(f"{text!r}: expected {model.n_joints} joint values in the model's "
                         "joint order and units", option="--home")
    return v * model.joint_scale()


def simulate_images(args: dict[str, Any]) -> None:
    """Render the stations and write images, STATIONS.csv, truth and camera files; `args`
    are ``simulate``'s arguments, all checked before any work."""
    for key, opt in (("orientation", "--orientation"), ("angle_noise", "--angle-noise"),
                     ("pivot", "--pivot"), ("point", "--point"), ("plane", "--plane"),
                     ("length", "--length"), ("radius", "--radius"), ("groups", "--groups"),
                     ("sigma_column", "--sigma-column")):
        if args.get(key):
            raise InputError("applies to measured positions, not to --images", option=opt)
    if args.get("kind", "tracker") != "tracker":
        raise InputError("--images renders camera stations; it takes no other --kind",
                         option="--kind")
    if args["board"] is None:
        raise InputError("--images needs the board: e.g. --board chessboard:9x6:25",
                         option="--board")
    errors, out, images = args["errors"], args["out"], args["images"]
    check_paths({"MODEL": args["model"], "--intrinsics": args["intrinsics"],
                 "--errors": None if errors in ("zero", "random") else errors},
                {"--out": out, "--truth-out": args["truth_out"],
                 "--camera-out": args["camera_out"]})
    for key, most in (("noise", MAX_NOISE), ("blur", MAX_BLUR)):
        if check_finite(args[key], f"--{key}") > most:
            raise InputError(f"{args[key]:g}: expected at most {most:g}", option=f"--{key}")
    with warnings_scope(args["strict"]):
        from kinecal.calibration.serial.simulate import read_truth
        from kinecal.vision.boards import parse_board
        from kinecal.vision.imaging import ImageConditions
        from kinecal.vision.intrinsics import CameraIntrinsics, read_intrinsics, write_intrinsics
        from kinecal.vision.stations import (
            render_arm_stations,
            write_images,
            write_scene_truth,
            write_stations,
        )

        board = parse_board(args["board"])
        m = load_model_arg(args["model"], args["base_link"], args["tip_link"])
        n = check_count(args["poses"], "--poses", bytes_per_item=2_000_000)
        err = errors if errors in ("zero", "random") else read_truth(Path(errors), m) - m.nominal
        cam = DEFAULT_CAMERA
        if args["intrinsics"] is not None:
            intr = read_intrinsics(args["intrinsics"])
            if not intr.size:
                raise InputError("the camera file gives no image size", file=args["intrinsics"])
            cam = {"K": intr.K, "dist": intr.dist, "size": tuple(intr.size)}
        with status(f"rendering {n} stations", args["quiet"]):
            scene = render_arm_stations(
                m, board, np.asarray(cam["K"]), np.asarray(cam["dist"]), cam["size"], n,
                setup=args["setup"], errors=err, q_home=home_joints(args["home"], m),
                seed=args["seed"], supersample=2,
                conditions=ImageConditions(blur=args["blur"], noise=args["noise"]))
        camera = CameraIntrinsics(scene.K, scene.dist, scene.size, source="render")
        write_outputs(more=[(images, lambda path: write_images(scene, path)),
                            (out, lambda path: write_stations(scene, path)),
                            (args["truth_out"], lambda path: write_scene_truth(scene, path)),
                            (args["camera_out"], lambda path: write_intrinsics(path, camera))],
                      quiet=args["quiet"])
    if not args["quiet"]:
        typer.echo(f"wrote {n} images to {images} and their joints to {out}", err=True)
