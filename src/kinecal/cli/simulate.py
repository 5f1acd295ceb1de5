"""Serial-arm command ``simulate``: synthetic measurements of a perturbed arm."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from kinecal._limits import check_count, check_finite
from kinecal.cli._app import app
from kinecal.cli._common import (
    MODEL_HELP,
    base_link_option,
    check_paths,
    load_model_arg,
    quiet_option,
    seed_option,
    strict_option,
    tip_link_option,
    warnings_scope,
)
from kinecal.cli._serial_common import POSE_BYTES
from kinecal.errors import InputError


@app.command()
def simulate(
    model: str = typer.Argument(..., help=MODEL_HELP),
    base_link: str | None = base_link_option(),
    tip_link: str | None = tip_link_option(),
    poses: int = typer.Option(..., "--poses", help="Number of random poses (a model with "
                              "markers measures every marker at each: poses x markers rows)."),
    noise: float = typer.Option(0.0, "--noise", help="Gaussian noise sigma per coordinate."),
    errors: str = typer.Option("random", "--errors", help="zero, random or TRUTH.json."),
    seed: int = seed_option(),
    out: Path = typer.Option(..., "--out", help="Measurement CSV to write."),
    truth_out: Path | None = typer.Option(None, "--truth-out", help="Truth JSON to write."),
    orientation: bool = typer.Option(False, "--orientation",
                                     help="Also measure the tool orientation (qw..qz columns)."),
    angle_noise: float = typer.Option(0.0, "--angle-noise",
                                      help="Orientation noise sigma (model angle unit)."),
    strict: bool = strict_option(),
    quiet: bool = quiet_option(),
) -> None:
    """Simulate measurements of a model with true errors and noise."""
    from kinecal.calibration.diagnostics.sizes import check_angle_noise
    from kinecal.calibration.serial.simulate import read_truth, write_truth
    from kinecal.calibration.serial.simulate import simulate as run
    from kinecal.io.measurements import write_measurements

    check_paths({"MODEL": model, "--errors": None if errors in ("zero", "random") else errors},
                {"--out": out, "--truth-out": truth_out})
    check_finite(noise, "--noise")
    check_finite(angle_noise, "--angle-noise")
    with warnings_scope(strict):
        m = load_model_arg(model, base_link, tip_link)
        check_count(poses, "--poses", bytes_per_item=POSE_BYTES * (m.n_joints + 10))
        if errors in ("zero", "random"):
            err: object = errors
        else:
            err = read_truth(Path(errors), m) - m.nominal
        if angle_noise and not orientation:
            raise InputError("--angle-noise needs --orientation", option="--angle-noise")
        to_rad = np.pi / 180.0 if m.angle_unit == "deg" else 1.0
        check_angle_noise(angle_noise * to_rad, "--angle-noise", f"{angle_noise:g} "
                          f"{m.angle_unit}")  # in the unit given (simulate checks the rest)
        sim = run(m, poses, errors=err, noise=noise, rng=seed, orientation=orientation,
                  angle_noise=angle_noise * to_rad)
        write_measurements(out, sim.data, m)
        if truth_out is not None:
            write_truth(truth_out, m, sim.true_params)
    if not quiet:
        typer.echo(f"wrote {poses} poses to {out}"
                   + (f", truth to {truth_out}" if truth_out else ""), err=True)
