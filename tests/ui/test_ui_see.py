"""The workbench in Chromium as a newcomer meets it, then See and Run on what they made.

First the README's section "In the browser: the workbench", done as written: its numbered
steps are read from the README and done by the controls they name (a bold word is a tab,
a box, then the next `code` word is the option chosen, a button or a slider of the page;
a control the README names that the page lacks fails the test) on the workbench
``kinecal ui`` makes (no model, no data: `kinecal.ui.serve`; tests/ui/test_ui_cli.py
starts the command itself). The time from the workbench's start to the calibrated arrows
on screen is printed (under two minutes asked; wall time is not asserted).

Then, on the bundled UR5 and its 1000 laser-tracker poses (docs/workbench.md's See and Run
views, whose screenshots these tests make): the robot is drawn and follows
the pose slider; the calibration run from the page (the command line in a worker process)
gives the CLI's numbers and shrinks the arrows; its report opens in the page; a second
run, validated on the held-out set, is compared side by side; the page answers while a
calibration runs.
"""

from __future__ import annotations

import json
import re
import time

import numpy as np
import pytest
from tests.ui.conftest import DOCS_IMG, ROOT, open_page

pytestmark = pytest.mark.slow

SECTION = "## In the browser: the workbench"


@pytest.fixture(scope="module")
def bench(workdir):
    from kinecal.ui.app import Workbench

    started = time.perf_counter()
    wb = Workbench(None, port=0, workdir="kinecal-ui")  # what `kinecal ui` serves
    wb.started = started
    yield wb
    wb.close()


@pytest.fixture(scope="module")
def page(browser, bench):
    p = open_page(browser, bench)
    yield p
    assert p.outside == [], f"the page reached outside 127.0.0.1: {p.outside}"
    p.page.context.close()


def readme_steps() -> tuple[list[str], list[list[tuple[str, str]]]]:
    """The section's shell lines and, per numbered step, its tokens in order:
    (``bold``, label) and (``code``, text)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index(SECTION):]
    section = section[:section.index("\n## ", len(SECTION))]
    shell = re.search(r"```sh\n(.*?)```", section, re.S).group(1).strip().splitlines()
    items = re.findall(r"^\d+\. (.*?)(?=^\d+\. |^\s*$)", section, re.M | re.S)
    steps = [[("bold", m.group(1)) if m.group(1) else ("code", m.group(2))
              for m in re.finditer(r"\*\*(.+?)\*\*|`([^`]+)`", item)] for item in items]
    return shell, steps


def do(page, label: str, following: list[tuple[str, str]]) -> str:
    """Do what a bold word of the README names; returns what it was."""
    p = page.page
    tab = p.get_by_role("tab", name=label, exact=True)
    if tab.count():
        tab.click()
        return "tab"
    box = p.get_by_role("combobox", name=label, exact=True)
    if box.count():
        option = next(text for kind, text in following if kind == "code")
        box.click()
        p.get_by_role("option", name=option, exact=True).click()
        page.wait_text("kc-status", option if option != "ur5" else "model ur5")
        return "box"
    button = p.get_by_role("button", name=label, exact=True)
    if button.count():
        button.click()
        return "button"
    ident = p.evaluate("""(label) => { for (const l of document.querySelectorAll('label'))
        if (l.innerText.trim() === label && l.htmlFor) {
          const e = document.getElementById(l.htmlFor);
          if (e && e.querySelector('[role=slider]')) return l.htmlFor; }
        return null; }""", label)
    if ident is not None:  # a slider: to the middle pose, typed in its number box
        box = p.locator(f'[id="{ident}"]').locator(
            "xpath=ancestor::div[contains(@class,'mantine-Flex-root')][1]//input").last
        box.fill("500")
        box.press("Enter")
        page.wait_text("kc-pose", "pose 500 of 1000")
        return "slider"
    raise AssertionError(f"the README names {label!r}: the page has no such control")


def test_the_readme_calibrates_the_ur5_in_the_page(page, bench, workdir):
    shell, steps = readme_steps()
    assert shell == ["pip install 'kinecal[ui]'", "kinecal ui"]
    assert len(steps) == 4
    done = []
    for step in steps:
        for k, (kind, label) in enumerate(step):
            if kind == "bold":
                done.append((label, do(page, label, step[k + 1:])))
            if done and done[-1] == ("Calibrate", "button"):
                page.wait_text("kc-run", "run 1: done", timeout=120_000)
                done.append(("calibrated", "run"))
    assert done == [("Model", "box"), ("Bundled data", "box"), ("Run", "tab"),
                    ("Calibrate", "button"), ("calibrated", "run"), ("See", "tab"),
                    ("Pose", "slider")]
    legend = page.wait_text("kc-legend", "after (run 1)")
    seconds = time.perf_counter() - bench.started
    print(f"\nnewcomer: the workbench started, the README's steps done, the calibrated "
          f"arrows shown in {seconds:.1f} s")
    result = json.loads((workdir / "kinecal-ui" / "run-1" / "result.json").read_text())
    # the arrows are the command line's errors: the same means before and after
    see = bench.see
    assert see.before.mean() == pytest.approx(result["calibration"]["before"]["mean"],
                                              rel=1e-9)
    assert see.after.mean() == pytest.approx(result["calibration"]["after"]["mean"],
                                             rel=1e-9)
    assert f"mean {result['calibration']['after']['mean']:.4g}" in legend
    assert result["calibration"]["before"]["mean"] > 5 * result["calibration"]["after"]["mean"]
    assert "$ kinecal calibrate ur5 ur5-laser-tracker:grid --method lm" in page.text("kc-run")
    words = page.text("kc-words")
    assert f"identify {result['rank']} of the 33 parameters" in words
    assert "d2: moves the tool exactly as" in words
    assert page.errors == []


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
    page.set_slider(bench.see.pose, 250)
    text = page.wait_text("kc-pose", "pose 250 of 1000")
    assert "error before" in text
    page.page.wait_for_timeout(800)
    moved = canvas(page.shot())
    assert changed(shown, moved) > 1000  # the arm moved to pose 250
    page.set_slider(bench.see.pose, 500)
    page.wait_text("kc-pose", "pose 500 of 1000")
    assert page.errors == []


def _arrow_colours(img):
    """Pixels of the red end and of the green end of the error ramp."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    warm = ((r > 170) & (b < 90) & (r - g > 25)).sum()  # yellow-orange-red: large errors
    green = ((g > 120) & (g - r > 40) & (g - b > 20)).sum()  # small errors
    return int(warm), int(green)


def test_the_arrows_shrink_after_calibration(page, bench):
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


def test_two_results_side_by_side(page, bench, workdir):
    page.choose(bench.bundled, "ur5-laser-tracker:random")
    page.wait_text("kc-status", "data ur5-laser-tracker:random: 20 poses")
    page.tab("Run")
    assert bench.run.validate.value == "ur5-laser-tracker:random"  # offered as validation
    page.el(bench.run.start).click()
    text = page.wait_text("kc-run", "run 2: done", timeout=120_000)
    assert "--validate ur5-laser-tracker:random" in text
    page.wait_text("kc-compare", "run 2")
    results = [json.loads((workdir / "kinecal-ui" / f"run-{k}" / "result.json").read_text())
               for k in (1, 2)]
    rows = page.page.locator("#kc-compare tr").all_inner_texts()
    table = {r.split("\t")[0]: r.split("\t")[1:] for r in rows[1:]}
    assert rows[0].split("\t")[1:] == ["run 1", "run 2"]
    for part in ("calibration", "validation"):
        for when in ("before", "after"):
            shown = table[f"{part} {when} mean"]
            wanted = [f"{r[part][when]['mean']:.4g}" if r.get(part) else "-"
                      for r in results]
            assert shown == wanted, (part, when, shown, wanted)
    assert table["validation after mean"][0] == "-"  # run 1 had no validation
    page.page.locator("#kc-pair-link").click()
    frames = page.page.locator("#kc-overlay iframe.kc-report")
    assert frames.count() == 2
    for k in range(2):
        h1 = page.page.frame_locator("#kc-overlay iframe.kc-report").nth(k).locator("h1")
        h1.first.wait_for(timeout=20_000)
    page.shot(DOCS_IMG / "workbench-compare.png")
    page.page.locator("#kc-overlay-close").click()


def test_the_page_answers_while_a_calibration_runs(page, bench):
    page.tab("Run")
    page.choose(bench.run.method, "pso")
    page.el(bench.run.start).click()
    page.wait_text("kc-run", "run 3: running")
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
    page.wait_text("kc-run", "run 3: stopped", timeout=60_000)
    assert bench.run.runs[-1].returncode == 143
