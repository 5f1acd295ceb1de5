"""The workbench in a real browser: Debian's Chromium (installed by ``make test`` through
.ci/install-chromium), driven by playwright's Python package (no browser download).

One browser for the session, one workbench per test module. The page is checked for leaving the
machine: every request it makes that is not to 127.0.0.1 is refused and recorded (the
page must work offline), and console errors are recorded.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
#: the machine notes' flags (no sandbox as root, no GPU, no background networking on a
#: closed network); WebGL then runs on SwiftShader, which Chromium asks to be allowed
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--enable-unsafe-swiftshader", "--force-device-scale-factor=1"]
ROOT = Path(__file__).resolve().parents[2]
DOCS_IMG = ROOT / "docs" / "img"
#: the Plan view's program languages (its dropdown's labels) and their suffixes
ROBOT_LANGUAGES = {"URScript (.script)": ".script", "ABB RAPID (.mod)": ".mod",
                   "KUKA KRL (.src)": ".src", "ROS 2 JointTrajectory (.yaml)": ".yaml"}


@pytest.fixture(scope="session")
def browser():
    if not Path(CHROMIUM).exists():
        pytest.fail("chromium is not installed: run `bash .ci/install-chromium` as root "
                    "(make test does it)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS, headless=True)
        yield b
        b.close()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A scratch working folder, the current one for the module (dropped files and runs
    are named relative to it, as the command line names them)."""
    folder = tmp_path_factory.mktemp("ui")
    old = os.getcwd()
    os.chdir(folder)
    yield folder
    os.chdir(old)


class Page:
    """A page of the workbench with helpers to drive viser's controls by their handles."""

    def __init__(self, page, bench):
        self.page, self.bench = page, bench
        self.outside: list[str] = []
        self.errors: list[str] = []

    def el(self, handle):
        return self.page.locator(f'[id="{handle._impl.uuid}"]')

    def text(self, ident: str) -> str:
        return self.page.locator(f"#{ident}").inner_text()

    def wait_text(self, ident: str, needle: str, timeout: float = 30_000) -> str:
        self.page.wait_for_function(
            "([i, n]) => { const e = document.getElementById(i); "
            "return e && e.innerText.includes(n); }", arg=[ident, needle], timeout=timeout)
        return self.text(ident)

    def choose(self, handle, option: str) -> None:
        """Pick `option` in a viser dropdown (Mantine select) as a user does."""
        self.el(handle).click()
        self.page.get_by_role("option", name=option, exact=True).click()

    def set_slider(self, handle, value, again: bool = False) -> None:
        """Type `value` into a viser slider's number box (`again`: the box may show the
        value already while the workbench missed it; it is emptied and typed key by key,
        so that the page sends it once more)."""
        box = self.page.locator(f'[id="{handle._impl.uuid}"]').locator(
            "xpath=ancestor::div[contains(@class,'mantine-Flex-root')][1]//input").last
        if again:
            box.fill("")
            box.press_sequentially(str(value))
        else:
            box.fill(str(value))
        box.press("Enter")

    def set_sliders(self, handles, values, timeout: float = 10.0) -> None:
        """Type `values` into sliders and wait until the workbench has them all (each
        update travels over the websocket on its own); a box whose typing the page lost
        while it redrew (seen under load) is typed again, twice at most."""
        import time

        pairs = list(zip(handles, values, strict=True))
        pending = pairs
        for attempt in range(3):
            for h, v in pending:
                self.set_slider(h, v, again=attempt > 0)
            end = time.monotonic() + timeout / 3
            while time.monotonic() < end:
                pending = [(h, v) for h, v in pairs if abs(float(h.value) - float(v)) > 1e-9]
                if not pending:
                    return
                time.sleep(0.02)
        raise AssertionError(f"sliders at {[h.value for h in handles]}, typed {list(values)}")

    def tab(self, name: str) -> None:
        self.page.get_by_role("tab", name=name, exact=True).click()

    def shot(self, path=None) -> np.ndarray:
        """Screenshot as an (H, W, 3) RGB array (and a PNG at `path`)."""
        import io

        from PIL import Image

        notice = self.page.get_by_text("Software WebGL rendering detected")
        if notice.count():  # viser's notice of software rendering: not part of the page
            notice.locator("xpath=ancestor::*[.//button][1]//button").first.click()
            notice.wait_for(state="hidden", timeout=3000)
        data = self.page.screenshot(path=None if path is None else str(path))
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def open_page(browser, bench, width=1400, height=900) -> Page:
    ctx = browser.new_context(viewport={"width": width, "height": height},
                              accept_downloads=True)
    page = ctx.new_page()
    p = Page(page, bench)

    def route(r):
        if r.request.url.startswith("http://127.0.0.1:"):
            return r.continue_()
        p.outside.append(r.request.url)
        return r.abort()

    page.route("**/*", route)
    page.on("console", lambda m: p.errors.append(m.text) if m.type == "error" else None)
    page.goto(bench.url)
    page.wait_for_selector("#kc-status", timeout=30_000)
    # headless Chromium draws WebGL in software: viser says so in a notice; closed here
    notice = page.get_by_text("Software WebGL rendering detected")
    try:
        notice.wait_for(timeout=5000)
        notice.locator("xpath=ancestor::*[.//button][1]//button").first.click(timeout=2000)
        notice.wait_for(state="hidden", timeout=3000)
    except Exception:
        pass
    return p
