"""Serial-arm command ``simulate``: synthetic measurements of a perturbed arm."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from kinecal._limits import check_count, check_finite
from kinecal.cli._app import app
from kinecal.cli._common import check_paths, warnings_scope
from kinecal.cli._options import (
    MODEL_HELP,
    angle_unit_option,
    base_link_option,
    check_angle_unit,
    choices,
    load_model_arg,
    quiet_option,
    seed_option,
    single_tip,
    strict_option,
    tip_links_option,
)
from kinecal.cli._outputs import write_outputs
from kinecal.cli._serial_common import POSE_BYTES
from kinecal.errors import InputError


@app.command()
def simulate(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
    tip: list[str] | None = typer.Option(None, "--tip", help="Robot system: the chains "
                                         "measured (repeatable; default every tip; --kind "
                                         "pair: the two hands the bar joins)."),
    carrier: str | None = typer.Option(None, "--carrier", help="Robot system, --kind point: "
                                       "the link carrying the points (e.g. a positioner's "
                                       "table); --point then in its frame."),
    poses: int | None = typer.Option(None, "--poses", help="Number of random poses (a model "
                                     "with markers measures every marker at each: poses x "
                                     "markers rows); gauge kinds: rows per pivot, pairs, "
                                     "touches per point or plane."),
    joints: str | None = typer.Option(None, "--joints", help="Tracker: CSV of joint values "
                                      "q1..qn (model angle unit; e.g. from select-poses) to "
                                      "measure instead of random poses."),
    kind: str = typer.Option("tracker", "--kind", metavar=choices(
        "tracker", "ballbar", "pair", "point", "plane"), help="tracker (x,y,z), ballbar "
                             "(pivot,distance), pair (pair,distance), point or plane "
                             "(docs/measurement-kinds.md)."),
    pivot: list[str] | None = typer.Option(None, "--pivot", help="Ballbar pivot X,Y,Z "
                                           "(repeatable; default 2 reachable pivots)."),
    point: list[str] | None = typer.Option(None, "--point", help="Fixed point X,Y,Z "
                                           "(repeatable; default 4 reachable points)."),
    plane: list[str] | None = typer.Option(None, "--plane", help="Plane X,Y,Z,NX,NY,NZ: a "
                                           "point and the normal (repeatable; default 2)."),
    length: float | None = typer.Option(None, "--length", help="Ballbar or bar length "
                                        "(length unit; default a quarter of the reach)."),
    radius: float | None = typer.Option(None, "--radius", help="Planes: touches within "
                                        "this distance of the plane's point (length unit)."),
    groups: int | None = typer.Option(None, "--groups", min=1, help="Number of default "
                                      "pivots, points or planes (default 2, 4, 2)."),
    sigma_column: bool = typer.Option(False, "--sigma-column", help="Gauge kinds: write the "
                                      "noise as each row's sigma column."),
    noise: float = typer.Option(0.0, "--noise", help="Gaussian noise sigma per coordinate "
                                "(model length unit, e.g. mm)."),
    errors: str = typer.Option("random", "--errors", metavar=choices("zero", "random",
                                                                     "TRUTH.json"),
                               help="True errors: none, random within the model's tolerances, "
                               "or those of a truth file (simulate --truth-out)."),
    seed: int = seed_option(),
    out: Path = typer.Option(..., "--out", help="Measurement CSV to write."),
    truth_out: Path | None = typer.Option(None, "--truth-out", help="Truth JSON to write."),
    orientation: bool = typer.Option(False, "--orientation",
                                     help="Also measure the tool orientation (qw..qz columns)."),
    angle_noise: float = typer.Option(0.0, "--angle-noise",
                                      help="Orientation noise sigma (model angle unit)."),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
    images: Path | None = typer.Option(None, "--images", help="Render board images of the "
                                       "poses into this folder (--out is then STATIONS.csv; "
                                       "--noise is image noise in grey levels). See "
                                       "docs/arm-from-images.md."),
    board: list[str] | None = typer.Option(None, "--board", help="With --images: the board; "
                                           "a rig's NAME:LINK:SPEC (repeatable; "
                                           "docs/rigs.md)."),
    camera: list[str] | None = typer.Option(None, "--camera", help="With --images: a rig's "
                                            "camera NAME:LINK[:intrinsics.yaml] "
                                            "(repeatable)."),
    setup: str = typer.Option("eye-in-hand", "--setup", help="With --images: eye-in-hand "
                              "or eye-to-hand."),
    home: str | None = typer.Option(None, "--home", help="With --images: joints q1,..,qn "
                                    "(model units) where the camera faces the board."),
    blur: float = typer.Option(0.0, "--blur", help="With --images: blur sigma (px)."),
    intrinsics: Path | None = typer.Option(None, "--intrinsics", help="With --images: the "
                                           "camera (default 800x600 px, f 900 px)."),
    camera_out: Path | None = typer.Option(None, "--camera-out", help="With --images: "
                                           "write the camera (ROS YAML)."),
    angle_unit: str | None = angle_unit_option("the --joints file's joint columns (the "
                                               "output keeps the model's)"),
) -> None:
    """Simulate measurements of a model with true errors and noise (any measurement kind;
    with --images, rendered board images of its stations)."""
    from kinecal.cli.systems import is_system_arg

    if images is not None:  # a rig's cameras and boards: docs/rigs.md
        from kinecal.cli.simulate_rig import is_rig_simulation, simulate_rig

        if is_rig_simulation(camera, board, is_system_arg(model, base_link, tip_link)):
            return simulate_rig(dict(locals()))
    elif camera:
        raise InputError("applies to --images only", option="--camera")
    from kinecal.cli.calibrate_rig import one_board

    board = one_board(board)
    if is_system_arg(model, base_link, tip_link):
        from kinecal.cli.systems import system_simulate

        if (poses is None) == (joints is None):
            raise InputError("expected --poses N (rows per chain, bars, touches per point "
                             "and tip) or --joints PLAN.csv, one of them", option="--poses")
        if check_angle_unit(angle_unit) and joints is None:
            raise InputError("applies to a --joints file", option="--angle-unit")
        return system_simulate(dict(locals()))
    for option, value in (("--tip", tip), ("--carrier", carrier)):
        if value:
            raise InputError("applies to a robot system (docs/systems.md)", option=option)
    tip_link = single_tip(tip_link)
    if (poses is None) == (joints is None):
        raise InputError("expected --poses N (random poses) or --joints FILE (given poses), "
                         "one of them", option="--joints" if joints is not None else "--poses")
    if joints is not None and (images is not None or kind != "tracker"):
        raise InputError("applies to tracker measurements (x,y,z) only", option="--joints")
    if check_angle_unit(angle_unit) and joints is None:
        raise InputError("applies to a --joints file", option="--angle-unit")
    if images is not None:  # rendered stations of the arm: its own module
        from kinecal.cli.simulate_images import simulate_images

        return simulate_images(dict(locals()))
    from kinecal.calibration.diagnostics.sizes import check_angle_noise
    from kinecal.calibration.serial.simulate import read_truth, write_truth
    from kinecal.calibration.serial.simulate import simulate as run
    from kinecal.io.measurements import write_measurements

    check_paths({"MODEL": model, "--errors": None if errors in ("zero", "random") else errors,
                 "--joints": joints}, {"--out": out, "--truth-out": truth_out})
    check_finite(noise, "--noise")
    check_finite(angle_noise, "--angle-noise")
    with warnings_scope(strict):
        m = load_model_arg(model, base_link, tip_link)
        q = marker = None
        if joints is not None:
            q, marker = _read_joints(m, joints, angle_unit)
            poses = len(q)
        check_count(poses, "--poses", bytes_per_item=POSE_BYTES * (m.n_joints + 10))
        if errors in ("zero", "random"):
            err: object = errors
        else:
            err = read_truth(Path(errors), m) - m.nominal
        gauge = dict(pivot=pivot, point=point, plane=plane, length=length, radius=radius,
                     groups=groups, sigma_column=sigma_column)
        if kind != "tracker":
            from kinecal.cli.calibrate_kinds import simulate_gauge

            return simulate_gauge(m, kind, err, poses=poses, noise=noise, seed=seed, out=out,
                                  truth_out=truth_out, quiet=quiet, gauge=gauge,
                                  orientation=bool(orientation or angle_noise))
        for option, value in gauge.items():
            if value:
                raise InputError("applies to the gauge kinds (--kind ballbar, pair, point, "
                                 "plane) only", option="--" + option.replace("_", "-"))
        if angle_noise and not orientation:
            raise InputError("--angle-noise needs --orientation", option="--angle-noise")
        to_rad = np.pi / 180.0 if m.angle_unit == "deg" else 1.0
        check_angle_noise(angle_noise * to_rad, "--angle-noise", f"{angle_noise:g} "
                          f"{m.angle_unit}")  # in the unit given (simulate checks the rest)
        sim = run(m, poses, errors=err, noise=noise, rng=seed, orientation=orientation,
                  angle_noise=angle_noise * to_rad, q=q, marker=marker)
        write_outputs(more=[(out, lambda path: write_measurements(path, sim.data, m)),
                            (truth_out, lambda path: write_truth(path, m, sim.true_params))],
                      quiet=quiet)
    if not quiet:
        typer.echo(f"wrote {poses} poses to {out}"
                   + (f", truth to {truth_out}" if truth_out else ""), err=True)


def _read_joints(model, spec: str, angle_unit: str | None = None):
    """Joint values ``(N, n)`` (rad) of a ``--joints`` CSV and its marker column (the marker
    index per row, or None: every row measured at every marker of the model)."""
    from kinecal.cli._common import resolve_data_path
    from kinecal.io.measurements import read_joints, read_markers

    path = resolve_data_path(spec, "--joints")
    q = read_joints(path, model, angle_unit=angle_unit)
    marker, names = read_markers(path, model)
    if marker is not None and tuple(names) != tuple(model.marker_names):
        raise InputError("a marker column needs a model with markers (its names)",
                         file=path)
    return q, marker
