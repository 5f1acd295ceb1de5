"""Options shared by the commands: their names, metavars (the valid values in ``--help``),
units in the help text, and the few checks that go with them (`check_unit`,
`load_model_arg`). Every command builds its options from here so that one option reads the
same everywhere.
"""

from __future__ import annotations

from typing import Any

from kinecal.errors import InputError

__all__ = ["CALIBRATION_METHOD_CHOICES", "MODEL_HELP", "UNITS", "angle_unit_option",
           "base_link_option", "check_angle_unit", "check_unit", "choices",
           "instrument_option", "load_model_arg", "note_option", "operator_option",
           "quiet_option", "report_option", "seed_option", "single_tip", "strict_option",
           "tip_link_option", "tip_links_option", "tip_option",
           "unit_option"]


def choices(*values: str) -> str:
    """The metavar of an option with a fixed set of values: ``[a|b|c]`` in ``--help``.

    The command checks the value itself (one line naming the option and the valid values,
    exit 2), so a metavar rather than a click type lists them.
    """
    return "[" + "|".join(values) + "]"


#: calibration methods (kinecal.calibration.serial.api.CALIBRATION_METHODS without the
#: hybrids, which are hybrid- and a metaheuristic; tests/cli/test_cli_papercuts.py checks it)
CALIBRATION_METHOD_CHOICES = ("lm", "householder", "ga", "pso", "afsa", "sa-iafsa", "gwo",
                              "igwo", "dlh-gwo-de", "de", "ga-hu2005", "pso-liu2008",
                              "de-storn1997", "hybrid-<metaheuristic>")


#: the values of ``--unit`` (kinecal.metrology.units.DISPLAY_UNITS)
UNITS = ("auto", "mm", "um", "m")


def unit_option() -> Any:
    """The ``--unit`` option: the length unit of a command's printed summary."""
    import typer

    return typer.Option("auto", "--unit", metavar=choices(*UNITS), help="Length unit of the "
                        "printed summary (auto: the model's, mm for a model in metres whose "
                        "errors are below 1 m); files and JSON keep the model's unit.")


def check_unit(unit: str) -> str | None:
    """A ``--unit`` value for a summary (None for auto); `InputError` when unknown."""
    if unit not in UNITS:
        raise InputError(f"unknown unit {unit!r}; expected one of {', '.join(UNITS)}",
                         option="--unit")
    return None if unit == "auto" else unit


def angle_unit_option(what: str = "the joint columns of the files read") -> Any:
    """The ``--angle-unit`` option: the unit of revolute joint columns in files."""
    import typer

    return typer.Option(None, "--angle-unit", metavar=choices("deg", "rad"),
                        help=f"Unit of {what} (default: the model's angle unit).")


def check_angle_unit(unit: str | None) -> str | None:
    """A ``--angle-unit`` value (None: the model's); `InputError` when unknown."""
    if unit not in (None, "deg", "rad"):
        raise InputError(f"unknown angle unit {unit!r}; expected deg or rad",
                         option="--angle-unit")
    return unit


def seed_option(help: str = "Random seed (an integer >= 0).") -> Any:
    """The ``--seed`` option: any integer >= 0 (negative seeds are refused, exit 2).

    The same seed gives the same result bit for bit; numpy's `SeedSequence` takes any
    non-negative integer, however large.
    """
    import typer

    return typer.Option(0, "--seed", min=0, help=help)


#: help text of a MODEL argument of every command that takes a serial-arm model
MODEL_HELP = "Bundled model name, model YAML or URDF file (see --base-link, --tip-link)."


def base_link_option() -> Any:
    """The ``--base-link`` option of commands that take a MODEL (URDF models only)."""
    import typer

    return typer.Option(None, "--base-link", help="URDF model: first link of the chain "
                        "(default: the root link).")


def tip_link_option() -> Any:
    """The ``--tip-link`` option of commands that take a MODEL (URDF models only)."""
    import typer

    return typer.Option(None, "--tip-link", help="URDF model: last link of the chain "
                        "(default: the end of the one branch with moving joints).")


def tip_links_option() -> Any:
    """The ``--tip-link`` option of the commands that take robot systems: repeatable."""
    import typer

    return typer.Option(None, "--tip-link", help="URDF model: last link of the chain "
                        "(default: the end of the one branch with moving joints); repeat it "
                        "for a system of several chains (docs/systems.md).")


def tip_option() -> Any:
    """The ``--tip`` option: the chain of a robot system that rows without a ``tip``
    column belong to."""
    import typer

    return typer.Option(None, "--tip", help="Robot system: the chain (tip link or part) of "
                        "every row of files without a tip column (docs/systems.md).")


def single_tip(tip_link: list[str] | str | None) -> str | None:
    """The one ``--tip-link`` of a serial chain (None when not given); several are a
    system's, which the command's system path took before."""
    if tip_link is None or isinstance(tip_link, str):
        return tip_link
    if len(tip_link) > 1:
        raise InputError(f"--tip-link given {len(tip_link)} times: several tips make a robot "
                         "system of a URDF tree (docs/systems.md)", option="--tip-link")
    return tip_link[0] if tip_link else None


def load_model_arg(model: str, base_link: str | None = None, tip_link: str | None = None):
    """Load a MODEL argument: bundled name, model YAML, or URDF with its chain ends
    (`base_link_option`, `tip_link_option`; an error when given for a non-URDF model)."""
    from kinecal.io.models import load_model

    return load_model(model, base_link=base_link, tip_link=tip_link)


def instrument_option() -> Any:
    """The ``--instrument`` option of commands that write a report (its record)."""
    import typer

    return typer.Option(None, "--instrument", help="Measuring instrument (make, model, serial "
                        "number), recorded in the --report.")


def operator_option() -> Any:
    """The ``--operator`` option of commands that write a report (its record)."""
    import typer

    return typer.Option(None, "--operator", help="Who measured and calibrated, recorded in "
                        "the --report.")


def note_option() -> Any:
    """The ``--note`` option of commands that write a report (its record)."""
    import typer

    return typer.Option(None, "--note", help="Free text recorded in the --report (site, "
                        "temperature, job number...).")


def report_option() -> Any:
    """The ``--report`` option: an HTML report, or PDF when the name ends in ``.pdf``."""
    import typer

    return typer.Option(None, "--report", help="Report to write: HTML, or PDF for a .pdf "
                        "name (needs the pdf extra). See docs/report.md.")


def strict_option() -> Any:
    """The ``--strict`` option every command that can warn shares."""
    import typer

    return typer.Option(False, "--strict",
                        help="Treat every plausibility warning as an error (exit 2).")


def quiet_option() -> Any:
    """The ``--quiet`` option: no progress and no summary text; warnings still print."""
    import typer

    return typer.Option(False, "--quiet",
                        help="No progress bar or summary (warnings are still printed).")
