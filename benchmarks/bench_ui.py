"""The workbench's See view: how long a pose slider's move takes to show, with the 1000
poses of the bundled UR5 set on screen (their points and 2000 error arrows, before and
after a calibration), in headless Chromium.

Run ``python benchmarks/bench_ui.py [--quick] [--moves N] [--size WxH]``.

One move is timed in the page, from the slider's new value entering the page (its number
box set and its change event fired, as a user typing into it) until a frame is painted
with the new pose: the pose line of the view shows it (the robot's cylinders and the pose
marker travel before it on the same websocket, in order) and two animation frames have
passed (the first runs before the paint of the updated scene, the second after it).

Peer: the floor of any viser page, a plain viser server (no kinecal code) showing the same
scene (the 1000 points and the 2000 arrows as point clouds and line-segment sets of the
same arrays) whose slider moves one marker to the pose's point and writes its value into
an HTML line: the websocket round trip and a repaint of the same scene. The ratio
kinecal / floor is what drawing the robot at the new pose adds. Also reported: the Python
time of the See view's handler per move and what it sends (bytes over the websocket).

Chromium renders WebGL in software here (SwiftShader, no GPU on this box): a user's GPU
paints faster, so these are upper bounds of the paint part.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: one move timed in the page (module docstring); arguments: the slider's id, the value,
#: the id of the element whose text shows it and the text awaited
MOVE_JS = """async ([slider, value, shown, needle]) => {
  const row = document.getElementById(slider).closest('.mantine-Flex-root');
  const boxes = row.querySelectorAll('input');
  const box = boxes[boxes.length - 1];
  // the line is replaced whole at each update: watched through its parent
  const parent = document.getElementById(shown).parentElement;
  const t0 = performance.now();
  const seen = new Promise((resolve) => {
    const obs = new MutationObserver(() => {
      const e = document.getElementById(shown);
      if (e && e.innerText.includes(needle)) { obs.disconnect(); resolve(); }
    });
    obs.observe(parent, {subtree: true, childList: true, characterData: true});
  });
  const setter = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, 'value').set;
  setter.call(box, String(value));
  box.dispatchEvent(new Event('input', {bubbles: true}));
  box.dispatchEvent(new KeyboardEvent('keydown', {key: 'Enter', bubbles: true}));
  box.dispatchEvent(new Event('change', {bubbles: true}));
  box.blur();
  await seen;
  const t1 = performance.now();
  await new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)));
  return [t1 - t0, performance.now() - t0];
}"""


def _calibrated_bench(folder: Path):
    """A workbench with the UR5's 1000 grid poses and the calibration of them."""
    from kinecal.cli import main
    from kinecal.ui.app import Workbench

    result = folder / "result.json"
    with contextlib.redirect_stderr(io.StringIO()):
        code = main(["calibrate", "ur5", "ur5-laser-tracker:grid", "--out", str(result),
                     "--quiet"])
    assert code == 0
    wb = Workbench("ur5", ["ur5-laser-tracker:grid"], port=0, workdir=folder / "ui")
    wb.load(str(result))
    assert wb.see.after is not None and len(wb.see.before) == 1000
    return wb


def _floor_server(wb):
    """The peer (module docstring): plain viser, the same scene arrays, an HTML line."""
    import viser

    from kinecal.ui.front import FrontServer

    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    see = wb.see
    for key in ("before", "after"):
        shafts, heads = see._handles[key]
        server.scene.add_line_segments(f"/{key}/shafts", np.asarray(shafts.points),
                                       np.asarray(shafts.colors), thickness=2.0,
                                       thickness_units="screen")
        server.scene.add_point_cloud(f"/{key}/heads", np.asarray(heads.points),
                                     colors=np.asarray(heads.colors),
                                     point_size=float(heads.point_size), point_shape="circle")
    measured = np.asarray(see.robot.skeleton.points[:, -1], dtype=np.float32)
    server.scene.add_point_cloud("/measured", measured, colors=(60, 60, 60),
                                 point_size=0.004, point_shape="circle")
    n = len(see.before)
    slider = server.gui.add_slider("Pose", min=1, max=n, step=1, initial_value=1)
    line = server.gui.add_html('<div id="kc-pose">pose 1</div>')
    marker = server.scene.add_icosphere("/marker", radius=0.01, color=(30, 90, 200))

    def moved(_):
        # the scene changes (a marker moves: the page repaints it), then the line
        marker.position = tuple(float(v) for v in measured[int(slider.value) - 1])
        line.content = f'<div id="kc-pose">pose {int(slider.value)} of {n}</div>'

    slider.on_update(moved)
    # served through the same front page as the workbench (its script and status box)
    front = FrontServer(0, server.get_port(), lambda name, data: (False, "no drops"))
    server.gui.add_html('<div id="kc-status">floor</div>')
    return server, front, slider


def _open(browser, url: str, size: tuple[int, int]):
    page = browser.new_page(viewport={"width": size[0], "height": size[1]})
    page.goto(url)
    page.wait_for_selector("#kc-pose", timeout=60_000)
    notice = page.get_by_text("Software WebGL rendering detected")
    with contextlib.suppress(Exception):
        notice.wait_for(timeout=3000)
        notice.locator("xpath=ancestor::*[.//button][1]//button").first.click(timeout=2000)
    page.wait_for_timeout(1500)
    return page


def _moves(page, slider_id: str, values, shown: str = "kc-pose") -> tuple[list, list]:
    seen, painted = [], []
    for v in values:
        a, b = page.evaluate(MOVE_JS, [slider_id, int(v), shown, f"pose {int(v)} of"])
        seen.append(a)
        painted.append(b)
    return seen, painted


def _handler_cost(wb, values) -> tuple[float, int]:
    """Python time (ms, median) of the See view's move and the bytes of the messages it
    sends (msgpack, median)."""
    import msgspec

    ws = wb.server._websock_server
    original = ws.queue_message
    sizes: list[int] = []

    def counting(message):
        buffers: list = []
        head = msgspec.msgpack.encode(message.as_serializable_dict(buffers))
        sizes.append(len(head) + sum(b.nbytes for b in buffers))
        original(message)

    times, sent = [], []
    ws.queue_message = counting
    try:
        for v in values:
            sizes.clear()
            t = time.perf_counter()
            wb.see.show_pose(int(v) - 1)
            times.append((time.perf_counter() - t) * 1e3)
            sent.append(sum(sizes))
    finally:
        ws.queue_message = original
    return statistics.median(times), int(statistics.median(sent))


def _summary(name: str, ms: list[float]) -> str:
    a = np.asarray(ms)
    return (f"{name:34s} median {np.median(a):7.1f} ms   p90 {np.percentile(a, 90):7.1f} ms"
            f"   max {a.max():7.1f} ms   ({len(a)} moves)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer moves (20)")
    ap.add_argument("--moves", type=int, default=None, help="moves per page (default 100)")
    ap.add_argument("--size", default="1400x900", help="the browser's viewport, WxH")
    args = ap.parse_args()
    moves = args.moves or (20 if args.quick else 100)
    size = tuple(int(v) for v in args.size.split("x"))
    chromium = "/usr/bin/chromium"
    if not Path(chromium).exists():
        print("bench_ui: skipped, no Chromium at /usr/bin/chromium")
        return
    from playwright.sync_api import sync_playwright
    from tests.ui.conftest import FLAGS

    rng = np.random.default_rng(0)
    values = rng.integers(1, 1001, moves)
    values[1:][values[1:] == values[:-1]] += 1
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        wb = _calibrated_bench(Path(tmp))
        server, front, slider = _floor_server(wb)
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=chromium, args=FLAGS,
                                            headless=True)
                kc = _open(browser, wb.url, size)
                floor = _open(browser, front.url, size)
                kc_id, floor_id = wb.see.pose._impl.uuid, slider._impl.uuid
                rounds = {"kinecal": ([], []), "floor": ([], [])}
                for chunk in np.array_split(values, 5):  # interleaved rounds
                    for name, page, ident in (("kinecal", kc, kc_id),
                                              ("floor", floor, floor_id)):
                        a, b = _moves(page, ident, chunk)
                        rounds[name][0].extend(a)
                        rounds[name][1].extend(b)
                browser.close()
            handler_ms, sent = _handler_cost(wb, values[:20])
        finally:
            front.close()
            server.stop()
            wb.close()
            os.chdir(ROOT)
    print(f"See view, UR5, 1000 poses shown (1000 points, 2000 arrows), viewport "
          f"{size[0]}x{size[1]}, headless Chromium (software WebGL)")
    print(_summary("kinecal: move -> pose shown", rounds["kinecal"][0]))
    print(_summary("kinecal: move -> frame painted", rounds["kinecal"][1]))
    print(_summary("floor (plain viser): -> shown", rounds["floor"][0]))
    print(_summary("floor (plain viser): -> painted", rounds["floor"][1]))
    ratio = np.median(rounds["kinecal"][1]) / np.median(rounds["floor"][1])
    print(f"kinecal / floor (median, to the painted frame): {ratio:.2f}x")
    print(f"See view's handler per move (Python, timing included): median {handler_ms:.2f} "
          f"ms, {sent} bytes sent")


if __name__ == "__main__":
    main()
