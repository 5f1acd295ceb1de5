"""Hostile bags for ``kinecal import``, third wave's leftovers: joints that freeze while
the tracker moves (or ``--still 1e9``), a FIFO named like a bag, 16-bit colour images,
two runs into one new folder, build folders left by a killed run, a tracker clock decades
off the joints'. Same contract as tests/cli/test_hostile_wave3_f_ros.py (whose bag writer
this reuses): exit 2 with one line naming the cause and nothing written, or a named
warning; never exit 1, a hang or a silent wrong row."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from rosbags.rosbag2 import Writer

from kinecal.errors import InputError
from kinecal.io.ros.output import _move_into_place


def _sibling(name):
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


w3 = _sibling("test_hostile_wave3_f_ros")
M, header, TS, UR = w3.M, w3.header, w3.TS, w3.UR
run, imp, rows, refused = w3.run, w3.imp, w3.rows, w3.refused
STATIONS, XYZ = w3.STATIONS, w3.XYZ
POINTS = ["--points", "/tracker/point"]


# ---- the measurement moves while the joints read still


def test_joints_frozen_while_the_tracker_moves_drop_that_dwell(tmp_path, capsys):
    """From the end of the second dwell the joint topic repeats its last value: before, one
    row averaged the points of stations 2 and 3 (hundreds of mm apart), silently."""
    frozen_from = 90  # the first sample after dwell 2 (30 samples a dwell, 30 a move)
    bag = w3.write_bag(tmp_path / "rec",
                       joints=lambda i, t, q: STATIONS[1] if i >= frozen_from else q)
    out = tmp_path / "rows.csv"
    code, codes, _ = run(imp(bag, out, *POINTS), capsys)
    assert code == 0 and codes == ["ros-dwell-moving"]
    got = rows(out)
    assert got.shape == (1, 9)  # the good dwell alone
    np.testing.assert_allclose(got[0, 6:], XYZ[0] * 1000.0, atol=1e-9)


def test_a_still_tolerance_that_takes_everything_is_refused(tmp_path, capsys):
    bag = w3.write_bag(tmp_path / "rec")
    out = tmp_path / "rows.csv"
    code, codes, errors = run(imp(bag, out, *POINTS, "--still", "1e9"), capsys)
    assert codes == ["ros-dwell-moving"]
    refused(code, errors, out, "none of the 1 dwells could be kept", "moving:",
            "/tracker/point moved")
    drift = float(errors[0].split("moved ")[1].split(" mm")[0])
    assert drift > 100.0  # mm: the stations are that far apart


def test_tracker_noise_is_no_motion(tmp_path, capsys):
    """0.05 mm of white noise per axis on the points: clean, every row the mean."""
    rng = np.random.default_rng(3)
    bag = w3.write_bag(tmp_path / "rec", point=lambda i, t, p: p + rng.normal(0, 5e-5, 3))
    out = tmp_path / "rows.csv"
    code, codes, _ = run(imp(bag, out, *POINTS), capsys)
    assert code == 0 and codes == []
    assert np.abs(rows(out)[:, 6:] - XYZ * 1000.0).max() < 0.05


# ---- clocks


def test_a_tracker_clock_decades_off_names_both_ranges(tmp_path, capsys):
    """Was: every dwell dropped for 'no /tracker/point message during the dwell'."""
    offset = 60 * 365.25 * 86400.0  # the joints stamped 60 years after the tracker (1970)
    path = tmp_path / "rec"
    with Writer(path, version=9) as w:
        cj = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=TS)
        cp = w.add_connection("/tracker/point", "geometry_msgs/msg/PointStamped", typestore=TS)
        for t, q, k in w3.timeline():
            msg = M("sensor_msgs/msg/JointState", header=header(t + 1.0 + offset), name=UR,
                    position=np.asarray(q, float), velocity=np.zeros(0), effort=np.zeros(0))
            w.write(cj, round(t * 1e9), TS.serialize_cdr(msg, msg.__msgtype__))
            if k is not None:
                p = XYZ[k]
                msg = M("geometry_msgs/msg/PointStamped", header=header(t + 1.0),
                        point=M("geometry_msgs/msg/Point", x=p[0], y=p[1], z=p[2]))
                w.write(cp, round(t * 1e9), TS.serialize_cdr(msg, msg.__msgtype__))
    out = tmp_path / "rows.csv"
    code, _, errors = run(imp(path, out, *POINTS), capsys)
    refused(code, errors, out, "/tracker/point: its 90 messages are stamped",
            "1970-01-01T00:00:01.000", "the joints of /joint_states 2030-01-01T",
            "do not overlap")


# ---- files that are no bag file


def test_a_fifo_named_like_a_bag_is_refused_not_waited_on(tmp_path):
    """Was: blocked forever reading the pipe (run in a process of its own with a time
    limit, so the test fails instead of hanging)."""
    fifo = tmp_path / "x.bag"
    os.mkfifo(fifo)
    folder = tmp_path / "rec"
    folder.mkdir()
    os.mkfifo(folder / "metadata.yaml")
    for bag in (fifo, folder):
        out = tmp_path / "rows.csv"
        proc = subprocess.run([sys.executable, "-m", "kinecal", "import", str(bag), "--model",
                               "ur5", "--joints", "/joint_states", "--out", str(out)],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2 and "FIFO" in proc.stderr, proc.stderr
        assert not out.exists()


# ---- images


@pytest.mark.parametrize("encoding", ["rgb16", "mono16", "bgr16"])
def test_sixteen_bit_images_are_written_as_sixteen_bit_pngs(tmp_path, capsys, encoding):
    """Was exit 1 (a broadcast error in the PNG writer)."""
    c = 1 if encoding == "mono16" else 3
    pixels = np.random.default_rng(4).integers(0, 65536, (48, 64, c)).astype(np.uint16)

    def image(t):
        return ("sensor_msgs/msg/Image", t, M(
            "sensor_msgs/msg/Image", header=header(t), height=48, width=64, encoding=encoding,
            is_bigendian=0, step=64 * c * 2, data=pixels.astype("<u2").view(np.uint8).ravel()))

    bag = w3.write_bag(tmp_path / "rec", image=image, info_k=w3.K_GOOD)
    out = tmp_path / "stations"
    code, codes, _ = run(imp(bag, out, *w3.IMAGES), capsys)
    assert code == 0 and codes == []
    files = sorted(out.glob("dwell_*.png"))
    assert len(files) == 3
    back = cv2.imread(str(files[0]), cv2.IMREAD_UNCHANGED)  # OpenCV gives BGR
    rgb = pixels[:, :, ::-1] if encoding == "bgr16" else pixels
    want = rgb[:, :, 0] if c == 1 else rgb[:, :, ::-1]
    assert back.dtype == np.uint16 and np.array_equal(back, want)


def test_a_folder_filled_by_another_run_meanwhile_is_left_alone(tmp_path):
    """Two runs into one new folder: the one that finishes second fails cleanly (was an
    OSError, exit 1) and leaves the first one's folder as it was."""
    out, tmp = tmp_path / "st", tmp_path / ".st.kinecal-import-1"
    out.mkdir()
    (out / "stations.csv").write_text("first run\n")
    tmp.mkdir()
    (tmp / "stations.csv").write_text("second run\n")
    with pytest.raises(InputError, match="filled by another run"):
        _move_into_place(tmp, out)
    assert (out / "stations.csv").read_text() == "first run\n"
    empty = tmp_path / "empty"
    empty.mkdir()  # an empty folder is replaced
    _move_into_place(tmp, empty)
    assert (empty / "stations.csv").read_text() == "second run\n" and not tmp.exists()


def test_two_runs_at_once_into_one_new_folder(tmp_path):
    bag = w3.write_bag(tmp_path / "rec", image=lambda t: w3._mono(t), info_k=w3.K_GOOD)
    out = tmp_path / "st"
    argv = [sys.executable, "-m", "kinecal", "import", str(bag), "--model", "ur5", "--joints",
            "/joint_states", *w3.IMAGES, "--out", str(out)]
    procs = [subprocess.Popen(argv, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    codes = sorted(code for code, _ in results)
    assert codes in ([0, 0], [0, 2]), results  # never exit 1
    assert sorted(p.name for p in out.iterdir()) == [
        "camera.yaml", "dwell_001.png", "dwell_002.png", "dwell_003.png",
        "robot_poses.csv", "stations.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec", "st"]  # nothing hidden left


def test_build_folders_of_killed_runs_are_removed_by_the_next(tmp_path, capsys):
    """A SIGKILL leaves .NAME.kinecal-import-PID behind; a later run removes those of
    processes that are gone, and leaves a running one's."""
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".st.kinecal-import-{dead.pid}"
    stale.mkdir()
    (stale / "dwell_001.png").write_bytes(b"half")
    alive = tmp_path / f".st.kinecal-import-{os.getppid()}"
    alive.mkdir()
    bag = w3.write_bag(tmp_path / "rec", image=lambda t: w3._mono(t), info_k=w3.K_GOOD)
    code, _, _ = run(imp(bag, tmp_path / "st", *w3.IMAGES), capsys)
    assert code == 0
    assert not stale.exists() and alive.exists()
