"""``kinecal reproduce PAPER``: run a paper's experiment and print its table beside ours."""

from __future__ import annotations

from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.cli._common import (
    check_paths,
    echo_json,
    quiet_requested,
    report_record,
    without_times,
)
from kinecal.cli._options import (
    choices,
    instrument_option,
    note_option,
    operator_option,
    report_option,
    seed_option,
)
from kinecal.cli._outputs import write_outputs
from kinecal.experiments import PAPERS, experiment_module


@app.command()
def reproduce(
    paper: str = typer.Argument(..., metavar=choices(*PAPERS), help="Paper id."),
    quick: bool = typer.Option(False, "--quick", help="Small version that runs in seconds."),
    json_out: bool = typer.Option(False, "--json", help="Print the table as JSON."),
    out: Path | None = typer.Option(None, "--out", help="Directory for result.json and figures."),
    seed: int = seed_option(),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bars."),
    report: Path | None = report_option(),
    instrument: str | None = instrument_option(),
    operator: str | None = operator_option(),
    note: str | None = note_option(),
) -> None:
    """Reproduce a paper's table (hu2005, li2024, zhao-yang, liu2008)."""
    module = experiment_module(paper)
    check_paths({}, {"--report": report}, folders={"--out": (out, ["result.json"])})
    record = report_record(report, {}, instrument, operator, note)
    result = without_times(module.run(quick=quick, seed=seed, out_dir=out,
                                      quiet=quiet_requested(quiet)))
    write_outputs(out=None if out is None else out / "result.json", result=result,
                  report=report, write_report=lambda path: _report(result, path, record),
                  quiet=quiet or json_out)
    if json_out:
        echo_json(result)
    else:
        typer.echo(module.render(result))


def _report(result: dict, path: Path, record) -> None:
    from kinecal.report.html import reproduce_report

    reproduce_report(result, path, provenance=record)
