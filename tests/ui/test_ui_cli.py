"""``kinecal ui`` as a command (README.md's section on the workbench, docs/workbench.md):
it serves the workbench's page on 127.0.0.1 and says where; without the ui extra it says
in one line what to install and exits 2."""

from __future__ import annotations

import re
import subprocess
import sys
import urllib.request

import pytest


def test_kinecal_ui_serves_the_page(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "kinecal", "ui", "--no-browser", "--port",
                             "0"], cwd=tmp_path, stderr=subprocess.PIPE,
                            stdout=subprocess.DEVNULL, text=True)
    try:
        line = proc.stderr.readline()
        found = re.fullmatch(r"kinecal workbench at (http://127\.0\.0\.1:(\d+)/) \(Ctrl-C "
                             r"stops it\)\n", line)
        assert found, line
        with urllib.request.urlopen(found.group(1), timeout=30) as answer:
            html = answer.read().decode("utf-8")
        assert "<title>kinecal workbench</title>" in html
        assert "/kinecal/static/workbench.js" in html
        # the page's websocket is viser's, on 127.0.0.1 too; no address outside it
        assert re.search(r"ws://127\.0\.0\.1:\d+", html)
        assert not re.search(r"(src|href)=\"https?://", html)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    assert proc.returncode in (143, -15)


@pytest.mark.parametrize("args", [["ui"], ["ui", "ur5", "--no-browser"]])
def test_without_the_ui_extra_one_line(tmp_path, args):
    """viser made unimportable (as where the extra is not installed)."""
    code = ("import sys; sys.modules['viser'] = None; from kinecal.cli import main; "
            f"sys.exit(main({args!r}))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, check=False)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr == ("kinecal: error: the workbench needs the ui extra: pip install "
                           "'kinecal[ui]'\n")
    assert list(tmp_path.iterdir()) == []  # nothing written
