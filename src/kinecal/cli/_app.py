"""The typer application object shared by every command module."""

from __future__ import annotations

import typer

from kinecal.cli._coercion import install

install()  # plain option values without pydantic (kinecal.cli._coercion)

app = typer.Typer(
    name="kinecal",
    help="Kinematic calibration of serial robots, hand-eye setups and parallel-link CMMs.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


def _print_version(value: bool) -> None:
    if value:
        from kinecal import __version__

        typer.echo(f"kinecal {__version__}")
        raise typer.Exit(0)


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", is_eager=True, callback=_print_version,
                                 help="Print kinecal's version and exit."),
) -> None:
    # A callback keeps every command a subcommand even when only one command module is
    # loaded (kinecal.cli loads just the module of the command it runs): typer would
    # otherwise make a lone command the whole program.
    pass
