"""The Check view in Chromium over a registry the command line made: a UR5 calibrated and
registered, checked once; the page lists it, shows its history as ``kinecal registry
history`` words it and its drift figure, and runs a check of poses measured after its
second joint slipped (by ``kinecal check`` in a worker process): the registry then holds
that check, with the verdict the page shows. Without ``--db`` the view says what it needs
in one line (docs/workbench.md's Check view; its screenshot is made here)."""

from __future__ import annotations

import contextlib
import io
import json

import pytest
from tests.ui.conftest import DOCS_IMG, open_page

pytestmark = pytest.mark.slow


def cli(*args) -> tuple[int, str]:
    from kinecal.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in args])
    return code, out.getvalue() + err.getvalue()


@pytest.fixture(scope="module")
def registry(workdir):
    """reg.db: SN-1 calibrated on 30 poses (2026-01-05), checked on 2026-02-01 (valid);
    slipped.csv: its 10 check poses after theta2 lost 0.05 deg."""
    steps = [
        ("simulate", "ur5", "--poses", 30, "--noise", 0.02, "--seed", 7, "--out",
         "factory.csv", "--truth-out", "truth.json"),
        ("calibrate", "ur5", "factory.csv", "--sigma", 0.02, "--out", "factory.json",
         "--quiet"),
        ("registry", "add", "SN-1", "factory.json", "--date", "2026-01-05", "--db", "reg.db"),
        ("simulate", "ur5", "--poses", 10, "--noise", 0, "--seed", 3, "--out",
         "check-poses.csv"),
        ("simulate", "ur5", "--joints", "check-poses.csv", "--errors", "truth.json",
         "--noise", 0.02, "--seed", 1, "--out", "check-1.csv"),
        ("check", "SN-1", "check-1.csv", "--date", "2026-02-01", "--db", "reg.db"),
    ]
    for args in steps:
        code, text = cli(*args)
        assert code == 0, (args, text)
    truth = json.loads((workdir / "truth.json").read_text())
    truth["errors"]["theta2"] += 0.05
    truth["parameters"]["theta2"] += 0.05
    (workdir / "slipped.json").write_text(json.dumps(truth))
    code, text = cli("simulate", "ur5", "--joints", "check-poses.csv", "--errors",
                     "slipped.json", "--noise", 0.02, "--seed", 2, "--out", "slipped.csv")
    assert code == 0, text
    return workdir / "reg.db"


@pytest.fixture(scope="module")
def bench(registry):
    from kinecal.ui.app import Workbench

    wb = Workbench("ur5", ["slipped.csv"], port=0, db=registry.name, workdir="kinecal-ui")
    yield wb
    wb.close()


@pytest.fixture(scope="module")
def page(browser, bench):
    p = open_page(browser, bench, width=1000, height=800)
    yield p
    assert p.outside == [], p.outside
    p.page.context.close()


def test_the_registry_is_shown(page, bench, registry):
    from kinecal.registry import open_registry
    from kinecal.registry.drift import drift_summary
    from kinecal.registry.views import history_text

    page.tab("Check")
    assert page.wait_text("kc-check", "1 robot(s)").startswith("registry ")
    fleet = page.text("kc-fleet")
    assert "SN-1" in fleet and "ur5" in fleet and "valid" in fleet
    with open_registry(str(registry), write=False) as reg:
        hist = reg.history("SN-1")
    # the history in the words of `kinecal registry history`
    assert page.text("kc-history") == history_text(hist, drift_summary(hist))
    assert "history of SN-1 (2 records)" in page.text("kc-history")
    width = page.page.wait_for_function(
        "() => { const i = document.getElementById('kc-drift'); "
        "return i && i.complete && i.naturalWidth; }", timeout=20_000).json_value()
    assert width > 300  # the drift figure, served by the page, is a real image
    page.shot(DOCS_IMG / "workbench-check.png")


def test_a_check_from_the_page_is_recorded(page, bench, registry):
    from kinecal.registry import open_registry

    page.tab("Check")
    page.el(bench.check.start).click()
    text = page.wait_text("kc-check-outcome", "(check 3", timeout=120_000)
    assert "$ kinecal check SN-1 slipped.csv --db" in text
    with open_registry(str(registry), write=False) as reg:
        last = reg.history("SN-1")["events"][-1]
    assert last["kind"] == "check" and last["id"] == 3
    # the slipped joint is found: not valid, and the page says the registry's verdict
    assert last["verdict"] in ("drifted", "recalibrate")
    assert text.startswith(f"SN-1: {last['verdict'].upper()} (check 3, of calibration 1)")
    page.wait_text("kc-history", "history of SN-1 (3 records)")


def test_without_db_one_line(browser, workdir):
    from kinecal.ui.app import Workbench

    wb = Workbench(None, port=0, workdir="kinecal-ui-nodb")
    try:
        p = open_page(browser, wb, width=900, height=600)
        p.tab("Check")
        assert p.text("kc-check").startswith("Start the workbench with --db DB")
        p.page.context.close()
    finally:
        wb.close()
