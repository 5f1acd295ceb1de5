"""``kinecal datasets``: the bundled measurement sets and example files, listed or written
into a folder (the files a docs walkthrough starts from)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import typer

from kinecal.cli._app import app
from kinecal.cli._common import check_paths, echo_json
from kinecal.errors import InputError


def _listing() -> list[dict]:
    from kinecal.datasets import DATASETS

    return [{"name": n, "license": d["license"], "files": list(d["parts"].values()),
             "parts": [f"{n}:{p}" for p in d["parts"]], "source": d["source"],
             "description": d["description"]} for n, d in DATASETS.items()]


@app.command()
def datasets(
    names: list[str] | None = typer.Argument(None, metavar="NAME", help="Sets to "
                                              "write (without: list them)."),
    out: Path = typer.Option(Path("."), "--out", help="Folder to write the files into "
                             "(created when missing)."),
    json_out: bool = typer.Option(False, "--json", help="Print the list as JSON."),
) -> None:
    """List the bundled data sets and example files, or write some into a folder."""
    from kinecal.datasets import DATASETS, files

    if not names:
        if json_out:
            echo_json({"datasets": _listing()})
            return
        for d in _listing():
            typer.echo(f"{d['name']} ({d['license']}): {', '.join(d['files'])}")
            typer.echo(f"  {d['description']}")
        return
    if json_out:
        raise InputError("lists the sets; give no NAME", option="--json")
    unknown = [n for n in names if n not in DATASETS]
    if unknown:
        raise InputError(f"unknown set {unknown[0]!r}; bundled: {', '.join(DATASETS)}",
                         option="NAME")
    plan = [(src, out / (f"{n}-LICENSE.txt" if src.name == "LICENSE" else src.name))
            for n in dict.fromkeys(names) for src in files(n)]
    check_paths({}, {}, folders={"--out": (out, [dst.name for _, dst in plan])})
    for src, dst in plan:  # refuse before writing anything
        if os.path.lexists(dst) and not _same_file_bytes(dst, src):
            raise InputError(f"{dst} exists and differs from the bundled file: remove it or "
                             "write elsewhere", option="--out")
    from kinecal._files import all_or_nothing, write_bytes_atomic

    out.mkdir(parents=True, exist_ok=True)
    with all_or_nothing():
        for src, dst in plan:
            write_bytes_atomic(dst, src.read_bytes())
    typer.echo(f"wrote {', '.join(str(dst) for _, dst in plan)}", err=True)


def _same_file_bytes(path: Path, bundled: Path) -> bool:
    """Whether `path` is a regular file with the bundled file's bytes (read in blocks, and
    no further than its size: a link to /dev/zero or /dev/full is not such a file)."""
    try:
        st = os.stat(path)
    except OSError:  # a dangling link
        return False
    size = bundled.stat().st_size
    if not stat.S_ISREG(st.st_mode) or st.st_size != size:
        return False
    with open(path, "rb") as a, open(bundled, "rb") as b:
        while block := b.read(1 << 20):
            if a.read(len(block)) != block:
                return False
    return True
