"""The calibration report in a real browser: headless Debian Chromium takes a screenshot;
every embedded figure must appear in it pixel for pixel at its size (drawn, not blank),
and the page must log no console error.

Chromium is installed by ``make test`` (``.ci/install-chromium``) when missing; this test
fails, not skips, without it, since the report is what users open.
"""

import base64
import re
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from kinecal.report.html import FIG_HEIGHT, FIG_WIDTH, calibration_report

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
#: flags of the machine notes (.library/env/machines/python.md): no sandbox as root, no
#: GPU, and no background networking on a closed network
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--force-device-scale-factor=1", "--enable-logging=stderr",
         "--v=0"]
WIDTH, HEIGHT = 1000, 7200


def screenshot(page: Path, tmp_path: Path, name: str) -> tuple[np.ndarray, list[str]]:
    """Screenshot (H, W, 3) BGR of `page` and the console lines Chromium logged."""
    if not Path(CHROMIUM).exists():
        pytest.fail("chromium is not installed: run `bash .ci/install-chromium` as root "
                    "(make test does it)")
    shot = tmp_path / f"{name}.png"
    cmd = [CHROMIUM, *FLAGS, f"--user-data-dir={tmp_path / ('profile-' + name)}",
           f"--window-size={WIDTH},{HEIGHT}", f"--screenshot={shot}", page.as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180, check=False)
    assert shot.exists(), f"no screenshot (exit {proc.returncode}): {proc.stderr[-2000:]}"
    console = [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
    return cv2.imread(str(shot), cv2.IMREAD_COLOR), console


def test_console_errors_are_detected(tmp_path):
    """Control: the console check below does see a page's console error."""
    page = tmp_path / "control.html"
    page.write_text('<!DOCTYPE html><html><body><p>control</p>'
                    '<script>console.error("kinecal-control-error")</script></body></html>',
                    encoding="utf-8")
    _, console = screenshot(page, tmp_path, "control")
    assert any("kinecal-control-error" in line for line in console)


def figures_in_screenshot(page: Path, tmp_path: Path, name: str, count: int) -> None:
    """Every embedded figure of `page` is drawn in Chromium's screenshot, in order."""
    shot, console = screenshot(page, tmp_path, name)
    assert console == [], console
    assert shot.shape == (HEIGHT, WIDTH, 3)
    text = page.read_text(encoding="utf-8")
    figures = [cv2.imdecode(np.frombuffer(base64.b64decode(m), np.uint8), cv2.IMREAD_COLOR)
               for m in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)]
    assert len(figures) == count
    gray = cv2.cvtColor(shot, cv2.COLOR_BGR2GRAY)
    tops = []
    for fig in figures:
        assert fig.shape == (FIG_HEIGHT, FIG_WIDTH, 3)
        match = cv2.matchTemplate(gray, cv2.cvtColor(fig, cv2.COLOR_BGR2GRAY),
                                  cv2.TM_SQDIFF_NORMED)
        best, _, (x, y), _ = cv2.minMaxLoc(match)
        assert best < 1e-3, f"figure not found in the screenshot (best {best:.3g})"
        region = shot[y:y + FIG_HEIGHT, x:x + FIG_WIDTH]
        assert region.shape == fig.shape
        assert np.abs(region.astype(int) - fig).max() <= 8  # the colours too
        # drawn: a real share of the region is neither white nor uniform
        assert 0.02 < (region.min(axis=2) < 230).mean() < 0.9
        assert region.std() > 20
        tops.append(y)
    # one below the other, in document order
    assert np.all(np.diff(tops) >= FIG_HEIGHT)


def test_report_figures_are_drawn_in_chromium(ur5_result, tmp_path):
    from kinecal.report.provenance import collect

    prov = collect({"DATA": Path(__file__)}, command=["kinecal", "calibrate"], operator="me")
    page = calibration_report(ur5_result, tmp_path / "report.html", provenance=prov)
    figures_in_screenshot(page, tmp_path, "report", 5)


def test_iso9283_report_is_drawn_in_chromium(tmp_path):
    from kinecal.data import RepeatedPoses
    from kinecal.metrology.iso9283 import iso9283
    from kinecal.report.iso9283 import iso9283_report

    rng = np.random.default_rng(0)
    cmd = rng.uniform(-500, 500, (5, 3))
    meas = cmd[:, None] + 0.05 + rng.normal(0, 0.01, (5, 30, 3))
    res = iso9283(RepeatedPoses(tuple(f"P{i}" for i in range(1, 6)), np.arange(1, 31), meas,
                                cmd))
    page = iso9283_report(res, tmp_path / "iso.html")
    figures_in_screenshot(page, tmp_path, "iso", 1)
