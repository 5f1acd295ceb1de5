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


def test_what_a_calibration_placed_is_drawn(tmp_path, monkeypatch):
    """A ballbar at two pivots and four sockets calibrated together: the See view draws
    every pivot and socket at the place the result JSON gives (scene units: metres), and
    those places are the simulated ones within a millimetre."""
    import contextlib
    import io
    import json

    import numpy as np

    from kinecal.cli import main
    from kinecal.ui.app import Workbench

    monkeypatch.chdir(tmp_path)
    for args in (["simulate", "irb120", "--kind", "ballbar", "--pivot", "350,0,450",
                  "--pivot", "0,-350,400", "--length", "150", "--poses", "25", "--noise",
                  "0.002", "--seed", "1", "--out", "ballbar.csv", "--truth-out",
                  "truth.json"],
                 ["simulate", "irb120", "--kind", "point", "--poses", "8", "--noise", "0.01",
                  "--errors", "truth.json", "--seed", "2", "--out", "sockets.csv"],
                 ["calibrate", "irb120", "ballbar.csv", "sockets.csv", "--sigma",
                  "ballbar.csv=0.002", "--sigma", "sockets.csv=0.01", "--out", "result.json",
                  "--quiet"]):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(
                io.StringIO()):
            assert main(args) == 0, args
    result = json.loads((tmp_path / "result.json").read_text())
    wanted = {f"{k} {u[k]}": u["xyz"] for e in result["kinds"] for u in e["unknowns"]
              for k in ("pivot", "point") if k in u}
    assert sum(n.startswith("pivot") for n in wanted) == 2
    assert sum(n.startswith("point") for n in wanted) >= 2
    wb = Workbench("irb120", ["ballbar.csv", "sockets.csv"], port=0, workdir="kinecal-ui")
    try:
        wb.load("result.json")
        shown = {p.name: p for p in wb.see.placed}
        assert set(shown) == set(wanted)
        handles = wb.see.instruments.handles
        assert len(handles) == len(wanted)
        for (sphere, label), (name, xyz) in zip(handles.values(), wanted.items(),
                                                strict=True):
            assert np.allclose(sphere.position, np.asarray(xyz) * 1e-3, atol=1e-9), name
            assert label.text == name
        pivots = sorted(tuple(np.round(shown[n].pose[:3, 3])) for n in shown
                        if n.startswith("pivot"))
        truth = sorted([(350.0, 0.0, 450.0), (0.0, -350.0, 400.0)])
        assert np.allclose(pivots, truth, atol=1.0)
    finally:
        wb.close()


def test_planes_cameras_and_boards_placed():
    """A plane n.p = d is drawn at its point nearest the base origin with z along n; a
    camera in the base frame (cam2base, or a rig's camera on world) is drawn, a board on
    the flange (target2flange) or a rig's mount on a link is listed as carried."""
    import numpy as np

    from kinecal.ui.instruments import placed_of

    n = np.array([0.0, 0.6, 0.8])
    X = np.eye(4)
    X[:3, 3] = [900.0, 100.0, 500.0]
    data = {"kinds": [{"unknowns": [{"plane": "table", "normal": n.tolist(),
                                     "offset": 250.0}]}],
            "X": X.tolist(), "X_frame": "cam2base", "board_pose": np.eye(4).tolist(),
            "board_frame": "target2flange",
            "cameras": {"left": {"link": "world", "pose": X.tolist()},
                        "wrist": {"link": "flange", "pose": np.eye(4).tolist()}},
            "boards": {"b1": {"link": "link_3", "pose": np.eye(4).tolist()}}}
    placed = {p.name: p for p in placed_of(data)}
    assert {n: p.attached for n, p in placed.items()} == {
        "plane table": "world", "camera": "world", "board": "flange",
        "camera left": "world", "camera wrist": "flange", "board b1": "link_3"}
    assert np.allclose(placed["camera left"].pose, X)
    plane, camera, board = placed["plane table"], placed["camera"], placed["board"]
    assert plane.name == "plane table" and plane.kind == "plane"
    assert np.allclose(plane.pose[:3, 3], 250.0 * n)
    assert np.allclose(plane.pose[:3, 2], n)
    R = plane.pose[:3, :3]
    assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    assert (camera.name, camera.attached) == ("camera", "world")
    assert np.allclose(camera.pose, X)
    assert (board.name, board.attached) == ("board", "flange")


def test_a_camera_on_the_flange_moves_with_the_arm():
    """A camera carried by the flange (cam2flange, a rig's camera on ``flange``) is drawn
    at ``F(q_i) X`` of the pose the slider shows (F: the model's end frame with the
    calibrated parameters), and follows the slider; a mount on a link the model lacks is
    hidden."""
    import numpy as np

    from kinecal.io.measurements import read_measurements
    from kinecal.io.models import load_model
    from kinecal.ui.app import Workbench

    model = load_model("ur5")
    meas = read_measurements("ur5-laser-tracker:random", model)
    X = np.eye(4)
    X[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    X[:3, 3] = [30.0, -20.0, 80.0]
    params = model.nominal.copy()
    params[model.index(["a2"])] += 1.5  # mm: a calibrated arm, not the nominal one
    data = {"X": X.tolist(), "X_frame": "cam2flange",
            "cameras": {"wrist": {"link": "flange", "pose": X.tolist()},
                        "head": {"link": "head_link", "pose": np.eye(4).tolist()}}}
    wb = Workbench("ur5", ["ur5-laser-tracker:random"], port=0, workdir="kinecal-ui")
    try:
        wb.see.set_result(params, "camera", data=data)
        carried = {p.name: h for p, h in wb.see.instruments.carried}
        assert set(carried) == {"camera", "camera wrist", "camera head"}
        for index in (0, 7, 13):
            wb.see.show_pose(index)
            want = model.fk(meas.q[index:index + 1], params)[0] @ X
            for name in ("camera", "camera wrist"):
                h = carried[name]
                assert h.visible
                assert np.allclose(h.position, want[:3, 3] * 1e-3, atol=1e-12), (name, index)
                w, x, y, z = h.wxyz
                R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                              [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                              [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
                assert np.allclose(R, want[:3, :3], atol=1e-9)
            assert not carried["camera head"].visible  # the UR5 has no head_link
    finally:
        wb.close()
