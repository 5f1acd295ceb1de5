"""docs/arm-from-images.md, run literally: the walkthrough's commands (its sh block) in a fresh
folder (``kinecal ...`` in this process, ``mkdir`` through the shell), the pasted summary
lines compared (numbers to 5 %: another BLAS or OpenCV build may move them a little), then
the page's Python blocks in the same folder."""

from __future__ import annotations

import contextlib
import io
import math
import re
import shlex
from pathlib import Path

import pytest

from kinecal.cli import main

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "arm-from-images.md"
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)")


def _blocks(text: str, lang: str) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", text, flags=re.S | re.M)


def _same(line: str, want: str) -> bool:
    a, b = NUMBER.findall(line), NUMBER.findall(want)
    if NUMBER.sub("#", line) != NUMBER.sub("#", want) or len(a) != len(b):
        return False
    return all(math.isclose(float(x), float(y), rel_tol=0.05, abs_tol=2e-3)
               for x, y in zip(a, b, strict=True))


def test_the_walkthrough_runs_as_written(tmp_path, monkeypatch):
    text = PAGE.read_text(encoding="utf-8")
    section = text.split("## Walkthrough on a rendered arm", 1)[1].split("\n## ", 1)[0]
    commands = [ln for ln in _blocks(section, "sh")[0].splitlines() if ln.strip()]
    pasted = [ln for ln in _blocks(section, "text")[0].splitlines() if ln.strip()]
    monkeypatch.chdir(tmp_path)
    out = ""
    for cmd in commands:
        argv = shlex.split(cmd)
        if argv[0] == "mkdir":
            Path(argv[1]).mkdir()
            continue
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(argv[1:]) == 0, cmd
        out = buf.getvalue()
    got = out.splitlines()
    for want, line in zip(pasted, got, strict=False):
        assert _same(line, want), (line, want)
    for name in ("calibrated.yaml", "result.json", "report.html", "truth.json", "camera.yaml"):
        assert (tmp_path / "scene" / name).is_file()
    for code in _blocks(text, "python"):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            exec(compile(code, str(PAGE), "exec"), {})  # the page's own code
        if "aligned_tool_errors" in code:
            lines = buf.getvalue().splitlines()
            nominal, calibrated = (float(NUMBER.findall(ln)[0]) for ln in lines)
            assert calibrated < 0.05 * nominal
            said = re.search(r"prints `nominal ([\d.]+) mm` and `calibrated ([\d.]+) mm`", text)
            assert nominal == pytest.approx(float(said.group(1)), rel=0.05)
            assert calibrated == pytest.approx(float(said.group(2)), rel=0.05)
