"""Files dropped on the page and files the page writes: a bad file gets the command line's
error text, word for word; a plan made by hand is saved as the CSV select-poses writes,
and its figures are those of the identifiability analysis."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from tests.ui.conftest import open_page

pytestmark = pytest.mark.slow

DROP = """([name, text]) => {
  const dt = new DataTransfer();
  dt.items.add(new File([text], name, {type: 'text/csv'}));
  for (const kind of ['dragenter', 'dragover', 'drop'])
    window.dispatchEvent(new DragEvent(kind, {dataTransfer: dt, bubbles: true,
                                               cancelable: true}));
}"""

CLEAR = """() => { const e = document.getElementById('kc-drop-message');
                   e.className = ''; e.textContent = ''; }"""


@pytest.fixture(scope="module")
def bench(workdir):
    from kinecal.ui.app import Workbench

    wb = Workbench("ur5", port=0, workdir="kinecal-ui")
    yield wb
    wb.close()


@pytest.fixture(scope="module")
def page(browser, bench):
    p = open_page(browser, bench)
    yield p
    assert p.outside == [], p.outside
    p.page.context.close()


def cli_error(args: list[str]) -> str:
    proc = subprocess.run([sys.executable, "-m", "kinecal", *args], capture_output=True,
                          text=True, timeout=120, check=False)
    assert proc.returncode == 2, proc.stderr
    return proc.stderr.strip().splitlines()[-1]


@pytest.mark.parametrize("name, text", [
    ("bad-row.csv", "q1,q2,q3,q4,q5,q6,x,y,z\n0,0,0,0,0,0,1,2,3\n0,0,0,zero,0,0,1,2,3\n"),
    ("five-joints.csv", "q1,q2,q3,q4,q5,x,y,z\n0,0,0,0,0,1,2,3\n"),
    ("empty.csv", ""),
])
def test_a_bad_file_dropped_gets_the_cli_error(page, bench, workdir, name, text):
    page.page.evaluate(CLEAR)
    page.page.evaluate(DROP, [name, text])
    page.page.wait_for_function("() => document.getElementById('kc-drop-message')"
                                ".className === 'kc-error'", timeout=20_000)
    shown = page.text("kc-drop-message")
    saved = f"kinecal-ui/dropped/{name}"
    assert (workdir / saved).read_text() == text  # kept as dropped
    assert shown == cli_error(["calibrate", "ur5", saved])
    assert page.text("kc-status") == shown
    page.page.locator("#kc-drop-message").click()


def test_a_good_file_dropped_is_loaded(page, bench):
    from kinecal.datasets import bundled_csv

    text = bundled_csv("ur5-laser-tracker:random").read_text()
    page.page.evaluate(CLEAR)
    page.page.evaluate(DROP, ["random.csv", text])
    page.wait_text("kc-drop-message", "data random.csv: tracker, 20 rows")
    page.wait_text("kc-pose", "of 20 (random.csv)")


def test_plan_by_hand_is_saved_as_select_poses_writes(page, bench, workdir):
    from kinecal.io.csvtable import read_table

    page.tab("Plan")
    rng = np.random.default_rng(3)
    wanted = rng.uniform(-150, 150, (8, 6)).round(1)
    for q in wanted:
        for sl, v in zip(bench.plan.sliders, q, strict=True):
            page.set_slider(sl, v)
        page.page.wait_for_timeout(150)
        page.el(bench.plan.add).click()
    text = page.wait_text("kc-plan", "plan: 8 poses")
    assert np.allclose(bench.session.plan / bench.session.model.joint_scale(), wanted,
                       atol=1e-9)
    # the figures are the analysis of `kinecal identifiability --data PLAN.csv`
    page.el(bench.plan.save_csv).click()
    page.wait_text("kc-saved", "plan.csv")
    path = workdir / "kinecal-ui" / "plans" / "plan.csv"
    cols = read_table(path, [f"q{i}" for i in range(1, 7)])
    assert np.allclose(np.stack([cols[f"q{i}"] for i in range(1, 7)], axis=1), wanted)
    out = subprocess.run([sys.executable, "-m", "kinecal", "identifiability", "ur5", "--data",
                          str(path)], capture_output=True, text=True, check=True).stdout
    rank = out.split("rank ")[1].split(" of ")
    assert f"rank {rank[0]} of {rank[1].split(';')[0]}" in text
    cond = out.split("condition number ")[1].split(" ")[0]
    assert f"condition number {float(cond):.3g}"[:20] in f"condition number " \
        f"{float(text.split('condition number ')[1].split()[0]):.3g}"
