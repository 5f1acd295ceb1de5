"""Files dropped on the page and files the page writes: a bad file gets the command line's
error text, word for word; a plan made by hand is saved as the CSV select-poses writes,
and its figures are those of the identifiability analysis (docs/workbench.md's Plan view
and drops; its Plan screenshot is made here)."""

from __future__ import annotations

import numpy as np
import pytest
from tests.ui.conftest import DOCS_IMG, open_page

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
    p = open_page(browser, bench, width=1000, height=700)  # a smaller 3D view draws faster
    yield p
    assert p.outside == [], p.outside
    p.page.context.close()


def cli(args: list[str]) -> tuple[int, str, str]:
    """``kinecal ARGS`` in this process (the command line's own entry point): status,
    stdout, stderr."""
    import contextlib
    import io

    from kinecal.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue(), err.getvalue()


def cli_error(args: list[str]) -> str:
    code, _, err = cli(args)
    assert code == 2, err
    return err.strip().splitlines()[-1]


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
    # the status line comes over viser's websocket, after the drop's own answer
    page.page.wait_for_function("(t) => document.getElementById('kc-status').innerText === t",
                                arg=shown, timeout=10_000)
    page.page.locator("#kc-drop-message").click()


def test_a_good_file_dropped_is_loaded(page, bench):
    from kinecal.datasets import bundled_csv

    text = bundled_csv("ur5-laser-tracker:random").read_text()
    page.page.evaluate(CLEAR)
    page.page.evaluate(DROP, ["random.csv", text])
    page.wait_text("kc-drop-message", "data random.csv: tracker, 20 rows")
    page.wait_text("kc-pose", "of 20 (random.csv)")


def test_plan_by_hand_is_saved_as_select_poses_writes(page, bench, workdir):
    import re

    from kinecal.io.csvtable import read_table

    page.tab("Plan")
    rng = np.random.default_rng(3)
    wanted = rng.uniform(-150, 150, (4, 6)).round(1)
    for k, q in enumerate(wanted):
        page.set_sliders(bench.plan.sliders, q)
        page.el(bench.plan.add).click()
        page.wait_text("kc-plan", f"plan: {k + 1} poses")
    text = page.text("kc-plan")
    page.page.locator("#kc-plan").scroll_into_view_if_needed()  # the figures in the shot
    page.shot(DOCS_IMG / "workbench-plan.png")
    assert np.allclose(bench.session.plan / bench.session.model.joint_scale(), wanted,
                       atol=1e-9)
    page.el(bench.plan.save_csv).click()
    page.wait_text("kc-saved", "plan.csv")
    path = workdir / "kinecal-ui" / "plans" / "plan.csv"
    cols = read_table(path, [f"q{i}" for i in range(1, 7)])
    assert np.allclose(np.stack([cols[f"q{i}"] for i in range(1, 7)], axis=1), wanted)
    # the figures are the analysis of `kinecal identifiability --data PLAN.csv`
    code, out, _ = cli(["identifiability", "ur5", "--data", path])
    assert code == 0
    rank, n, cond = re.match(r"rank (\d+) of (\d+); condition number (\S+)", out).groups()
    shown = re.search(r"rank (\d+) of (\d+); condition number (\S+)", text).groups()
    assert shown[:2] == (rank, n) and int(rank) < int(n)  # 4 poses cannot identify all
    assert float(shown[2]) == pytest.approx(float(cond), rel=5e-3)  # 4 vs 3 digits shown
    held = re.search(r"held at nominal: (.*)", text).group(1).split(", ")
    assert len(held) == int(n) - int(rank)


def test_robot_programs_saved_from_the_plan(page, bench, workdir):
    """The plan of the test above as each robot language (the writers of select-poses
    --program): its joint values read back by each language's parser, in plan order."""
    from tests.ui.conftest import ROBOT_LANGUAGES

    page.tab("Plan")
    plan = bench.session.plan
    assert plan is not None and len(plan) == 4
    for label, suffix in ROBOT_LANGUAGES.items():
        page.choose(bench.plan.language, label)
        page.page.wait_for_function("([id, v]) => document.querySelector(`[id='${id}']`)"
                                    ".value === v", arg=[bench.plan.language._impl.uuid,
                                                         label], timeout=5000)
        page.el(bench.plan.save_program).click()
        page.wait_text("kc-saved", f"plan{suffix}")
        path = workdir / "kinecal-ui" / "plans" / f"plan{suffix}"
        joints = _program_joints(path.read_text(), suffix)
        assert np.allclose(joints, plan, atol=1e-8), (suffix, joints)


def _program_joints(text: str, suffix: str) -> np.ndarray:
    """Joint values (rad) of a program, by the parsers of tests/io/test_robot_programs.py
    (the writers' own tests: one parser per language)."""
    import yaml
    from tests.io import test_robot_programs as parsers

    if suffix == ".script":
        moves, waits = parsers.parse_urscript(text)
    elif suffix == ".mod":
        moves, _, waits = parsers.parse_rapid(text)
        moves = np.radians(moves)
    elif suffix == ".src":
        found, waits = parsers.parse_krl(text)
        moves = np.radians([[m[f"A{i}"] for i in range(1, 7)] for m in found])
    else:
        doc = yaml.safe_load(text)
        moves = np.array([p["positions"] for p in doc["points"]])
        waits = [2.0] * len(moves)
        from kinecal.io.ros.joints import UR_JOINTS

        assert doc["joint_names"] == list(UR_JOINTS)  # the UR driver's, as select-poses
    assert len(waits) == len(moves)
    return np.asarray(moves)


def test_select_poses_and_a_plan_file(page, bench, workdir):
    """Select poses runs kinecal select-poses in a worker process and loads what it wrote;
    a joints-only CSV dropped on the page becomes the plan."""
    from kinecal.io.csvtable import read_table

    page.tab("Plan")
    bench.plan.count.value = 12  # the number boxes, set as the page's own state
    bench.plan.candidates.value = 300
    page.el(bench.plan.select).click()
    status = page.wait_text("kc-status", "select-poses chose", timeout=120_000)
    assert status == ("select-poses chose 12 poses: kinecal select-poses ur5 --count 12 "
                      "--candidates 300 --out kinecal-ui/plans/selected.csv")
    cols = read_table(workdir / "kinecal-ui" / "plans" / "selected.csv",
                      [f"q{i}" for i in range(1, 7)])
    selected = np.stack([cols[f"q{i}"] for i in range(1, 7)], axis=1)
    assert np.allclose(bench.session.plan / bench.session.model.joint_scale(), selected)
    page.wait_text("kc-plan", "plan: 12 poses")
    text = "q1,q2,q3,q4,q5,q6\n" + "".join(
        ",".join(f"{v:g}" for v in row) + "\n" for row in selected[:3])
    page.page.evaluate(CLEAR)
    page.page.evaluate(DROP, ["three.csv", text])
    page.wait_text("kc-drop-message", "plan three.csv: 3 poses")
    page.wait_text("kc-plan", "plan: 3 poses")
