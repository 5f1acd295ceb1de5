"""See and Run in Chromium: the bundled UR5 and its 1000 laser-tracker poses; the robot is
drawn and follows the pose slider; a calibration run from the page (the command line in
a worker process) gives the CLI's numbers, shrinks the arrows, opens its report; the page
answers while a calibration runs."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tests.ui.conftest import DOCS_IMG, open_page

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def bench(workdir):
    from kinecal.ui.app import Workbench

    wb = Workbench("ur5", ["ur5-laser-tracker:grid", "ur5-laser-tracker:random"], port=0,
                   workdir=workdir / "kinecal-ui")
    yield wb
    wb.close()


@pytest.fixture(scope="module")
def page(browser, bench):
    p = open_page(browser, bench)
    p.wait_text("kc-pose", "pose 1 of 1000")
    p.page.wait_for_timeout(1500)  # the scene's first frames
    yield p
    assert p.outside == [], f"the page reached outside 127.0.0.1: {p.outside}"
    p.page.context.close()


def canvas(img: np.ndarray) -> np.ndarray:
    """The 3D view's part of a screenshot (left of the control panel, below viser's
    notices)."""
    return img[170:, : img.shape[1] - 460]


def changed(a: np.ndarray, b: np.ndarray) -> int:
    return int((np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 30).sum())


def test_robot_is_drawn_and_follows_the_slider(page, bench):
    shown = canvas(page.shot(DOCS_IMG / "workbench-see.png"))
    bench.see.robot.set_visible(False)
    page.page.wait_for_timeout(800)
    hidden = canvas(page.shot())
    bench.see.robot.set_visible(True)
    page.page.wait_for_timeout(800)
    robot_pixels = changed(shown, hidden)
    assert robot_pixels > 2000, robot_pixels  # the arm covers a real area of the view
    page.set_slider(bench.see.pose, 500)
    text = page.wait_text("kc-pose", "pose 500 of 1000")
    assert "error before" in text
    page.page.wait_for_timeout(800)
    moved = canvas(page.shot())
    assert changed(shown, moved) > 1000  # the arm moved to pose 500
    assert page.errors == []


def _arrow_colours(img):
    """Pixels of the red end and of the green end of the error ramp."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    warm = ((r > 170) & (b < 90) & (r - g > 25)).sum()  # yellow-orange-red: large errors
    green = ((g > 120) & (g - r > 40) & (g - b > 20)).sum()  # small errors
    return int(warm), int(green)


def test_calibrate_in_the_page(page, bench, workdir):
    page.tab("Run")
    page.el(bench.run.start).click()
    text = page.wait_text("kc-run", "run 1: done", timeout=120_000)
    assert "$ kinecal calibrate ur5 ur5-laser-tracker:grid --validate " \
           "ur5-laser-tracker:random --method lm" in text
    result = json.loads((workdir / "kinecal-ui" / "run-1" / "result.json").read_text())
    # the arrows are the command line's errors: the same means before and after
    see = bench.see
    assert see.before.mean() == pytest.approx(result["calibration"]["before"]["mean"],
                                              rel=1e-9)
    assert see.after.mean() == pytest.approx(result["calibration"]["after"]["mean"],
                                             rel=1e-9)
    words = page.text("kc-words")
    assert f"identify {result['rank']} of the 33 parameters" in words
    assert "d2: moves the tool exactly as" in words
    page.tab("See")
    page.wait_text("kc-legend", "after (run 1)")
    page.el(bench.see.show_after).click()  # before only
    page.page.wait_for_timeout(1000)
    before = _arrow_colours(canvas(page.shot(DOCS_IMG / "workbench-before.png")))
    page.el(bench.see.show_after).click()
    page.el(bench.see.show_before).click()  # after only
    page.page.wait_for_timeout(1000)
    after = _arrow_colours(canvas(page.shot(DOCS_IMG / "workbench-after.png")))
    page.el(bench.see.show_before).click()
    # large errors (yellow to red) before, small ones (green) after
    assert before[0] - after[0] > 500 and before[0] > 5 * before[1], (before, after)
    assert after[1] - before[1] > 500 and after[1] > 5 * after[0], (before, after)


def test_report_opens_in_the_page(page, bench):
    page.tab("Run")
    page.page.locator("#kc-report-link").click()
    frame = page.page.frame_locator("#kc-overlay iframe.kc-report").first
    frame.locator("h1").first.wait_for(timeout=20_000)
    assert "calibration" in frame.locator("h1").first.inner_text().lower()
    assert page.page.locator("#kc-overlay").is_visible()
    page.shot(DOCS_IMG / "workbench-report.png")
    page.page.locator("#kc-overlay-close").click()
    assert not page.page.locator("#kc-overlay").is_visible()


def test_the_page_answers_while_a_calibration_runs(page, bench):
    page.tab("Run")
    page.choose(bench.run.method, "pso")
    page.el(bench.run.start).click()
    page.wait_text("kc-run", "run 2: running")
    page.page.wait_for_function("() => /: [1-9][0-9]*( it\\.|\\/[0-9]+)/.test("
                                "document.getElementById('kc-run').innerText)",
                                timeout=60_000)  # iterations reported as they come
    page.tab("See")
    for k in (10, 20, 30):
        page.set_slider(bench.see.pose, k)
        page.wait_text("kc-pose", f"pose {k} of 1000", timeout=5_000)
    assert bench.run.runs[-1].running  # the page answered during the run
    page.tab("Run")
    page.el(bench.run.stop).click()
    page.wait_text("kc-run", "run 2: stopped", timeout=60_000)
    assert bench.run.runs[-1].returncode == 143
