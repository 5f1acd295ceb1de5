"""The README tutorial, run literally: every ``$ command`` of its code blocks, in order, in a
fresh folder, through bash, with the output compared to the text pasted under it.

The README promises "every command below was run as shown; the output is pasted unedited".
This test keeps that true: numbers are compared to 1 % (another BLAS may move the last
digit), times in seconds are not compared, everything else must match. A plain
``kinecal ...`` line runs in this process with the argv the shell would give it; a line
with shell syntax (pipes, redirections, ``echo $?``) runs through bash with this
checkout's ``kinecal`` first on the PATH. When a change of
kinecal changes what a tutorial command prints, paste the new output into README.md: the
failure message shows it.

Also checked: every relative link of README.md and docs/*.md points inside the repository
to a file that exists (and to a heading that exists, for ``#anchor`` links).
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
#: a duration: "0.038 s", "(about 1 min)"; its number is not compared
SECONDS = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)? s\b")


def tutorial_steps(text: str) -> list[tuple[str, list[str]]]:
    """``(command, expected output lines)`` of every ``$`` line of the tutorial section."""
    section = text.split("## A five-minute tutorial", 1)[1].split("\n## ", 1)[0]
    steps: list[tuple[str, list[str]]] = []
    for block in re.findall(r"^```[^\n]*\n(.*?)^```", section, flags=re.S | re.M):
        for line in block.splitlines():
            if line.startswith("$ "):
                steps.append((line[2:], []))
            elif steps:
                steps[-1][1].append(line)
    return steps


def _same_line(expected: str, actual: str) -> bool:
    """Same text; numbers within 1 % (or 1e-6: round-off noise); durations not compared."""
    expected, actual = SECONDS.sub("<t> s", expected), SECONDS.sub("<t> s", actual)
    if NUMBER.sub("#", expected) != NUMBER.sub("#", actual):
        return False
    return all(math.isclose(float(a), float(b), rel_tol=0.01, abs_tol=1e-6)
               for a, b in zip(NUMBER.findall(expected), NUMBER.findall(actual), strict=True))


@pytest.fixture(scope="module")
def shim(tmp_path_factory) -> dict[str, str]:
    """Environment whose ``kinecal`` is this checkout's command line."""
    bin_dir = tmp_path_factory.mktemp("bin")
    exe = bin_dir / "kinecal"
    exe.write_text(f'#!/bin/sh\nexec "{sys.executable}" -c '
                   f'"from kinecal.cli import main; main()" "$@"\n', encoding="utf-8")
    exe.chmod(0o755)
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
               PYTHONPATH=str(ROOT / "src"), COLUMNS="200")
    env.pop("KINECAL_DEBUG", None)
    return env


def _run_in_process(argv: list[str], cwd: Path) -> tuple[int, str]:
    """``kinecal ARGS`` in this process (a new interpreter per command costs about a
    second): the same argv the shell would pass, stdout and stderr into one stream, in
    the order they are written, as on a terminal."""
    import contextlib
    import io

    from kinecal.cli import main

    buf = io.StringIO()
    old = Path.cwd()
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
            code = main(argv)
    finally:
        os.chdir(old)
    return code, buf.getvalue()


def test_the_tutorial_runs_as_written(tmp_path, shim):
    steps = tutorial_steps(README.read_text(encoding="utf-8"))
    assert len(steps) >= 12
    status = 0
    for command, expected in steps:
        if command.startswith("kinecal ") and not re.search(r"[|;&<>$`'\"\\]", command):
            status, output = _run_in_process(command.split()[1:], tmp_path)
        else:  # shell syntax: through bash; `( exit N )` first, so `echo $?` sees status N
            proc = subprocess.run(["bash", "-c", f"( exit {status} ); {command}"],
                                  cwd=tmp_path, env=shim, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True, timeout=300)
            status, output = proc.returncode, proc.stdout
        actual = output.rstrip("\n").splitlines()
        while expected and not expected[-1].strip():
            expected = expected[:-1]
        ok = len(actual) == len(expected) and all(
            _same_line(e, a) for e, a in zip(expected, actual, strict=True))
        assert ok, (f"README tutorial step `$ {command}` (exit {status}) printed:\n"
                    + output + "\n--- README.md shows:\n" + "\n".join(expected))
        if not command.rstrip().endswith("echo $?"):  # else the status is in the output
            is_error = any(line.startswith("kinecal: error:") for line in expected)
            assert status == (2 if is_error else 0), f"`$ {command}` exited {status}"


def _anchors(path: Path) -> set[str]:
    out = set()
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("#"):
            title = line.lstrip("#").strip().lower()
            out.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return out


def test_doc_links_stay_inside_the_repository():
    pages = [README, *sorted((ROOT / "docs").glob("*.md"))]
    bad = []
    for page in pages:
        text = page.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+://|mailto:", target):
                continue
            file, _, anchor = target.partition("#")
            dest = (page.parent / file).resolve() if file else page
            if ROOT not in dest.parents and dest != ROOT:
                bad.append(f"{page.name}: {target} leaves the repository")
            elif not dest.exists():
                bad.append(f"{page.name}: {target} does not exist")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                bad.append(f"{page.name}: {target} has no such heading")
    assert bad == []


def test_every_docs_page_is_linked_from_the_index_and_the_readme():
    index = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    readme = README.read_text(encoding="utf-8")
    pages = [p.name for p in sorted((ROOT / "docs").glob("*.md")) if p.name != "index.md"]
    assert [p for p in pages if f"]({p})" not in index] == []
    assert [p for p in pages if f"](docs/{p}" not in readme] == []
