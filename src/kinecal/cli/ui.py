"""``kinecal ui``: the workbench in the browser (`kinecal.ui`, docs/workbench.md)."""

from __future__ import annotations

import os

import typer

from kinecal.cli._app import app
from kinecal.cli._options import MODEL_HELP, base_link_option, tip_links_option
from kinecal.errors import InputError


@app.command()
def ui(
    model: str | None = typer.Argument(None, help=MODEL_HELP + " (optional: chosen in the "
                                       "page otherwise)."),
    data: list[str] | None = typer.Argument(None, help="Measurement CSV(s) or NAME:PART to "
                                            "open with the model."),
    port: int = typer.Option(8080, "--port", help="Port of the page on 127.0.0.1 (0: any "
                             "free port)."),
    db: str | None = typer.Option(None, "--db", help="Registry of the Check view: a SQLite "
                                  "file or a postgresql:// URL (default $KINECAL_DB)."),
    no_browser: bool = typer.Option(False, "--no-browser", help="Print the address; do not "
                                    "open a browser."),
    base_link: str | None = base_link_option(),
    tip_link: list[str] | None = tip_links_option(),
) -> None:
    """Open the workbench: see the robot, its poses and errors; plan poses; calibrate;
    check (served on 127.0.0.1 only, no network needed)."""
    if not 0 <= port <= 65535:
        raise InputError(f"expected a port from 0 to 65535, got {port}", option="--port")
    if data and model is None:
        raise InputError("DATA needs a MODEL before it", option="DATA")
    try:
        import viser  # noqa: F401
    except ImportError:
        raise InputError("the workbench needs the ui extra: pip install 'kinecal[ui]'") from None
    from kinecal.ui import serve

    db = db if db is not None else os.environ.get("KINECAL_DB")
    serve(model, data or (), port=port, db=db, open_browser=not no_browser,
          base_link=base_link, tip_links=tip_link or (),
          echo=lambda text: typer.echo(text, err=True))
