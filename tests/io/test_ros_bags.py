"""``kinecal import BAG``: bags written here with rosbags itself (ROS 2 sqlite3 and mcap,
ROS 1), a UR5 at 50 Hz dwelling at stations with a tracker's points during the dwells;
the imported rows are the dwells', partial dwells dropped with their reasons."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from kinecal.cli import main
from kinecal.io.csvtable import read_table
from kinecal.io.models import load_model
from kinecal.io.ros.accumulate import TfTree
from kinecal.io.ros.dwell import DwellFinder
from kinecal.spatial import pq_from_transform, transform_from_pq

#: ROS 2's joint_state_broadcaster order for a UR arm (not the arm's order)
UR2_NAMES = ["shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint", "shoulder_pan_joint"]
RATE, DWELL, MOVE = 50, 0.8, 1.2
PARTIAL, MISSING = 2, 4  # dwells (0-based) whose tracker stream is partial / missing


class BagWriter:
    """One writer for ROS 2 (sqlite3, mcap) and ROS 1 bags."""

    def __init__(self, path, kind):
        self.ros1 = kind == "ros1"
        self.ts = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        if self.ros1:
            self.w = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
            self.w = Writer2(path, version=9, storage_plugin=plugin)
        self.w.open()
        self.conns = {}

    def T(self, name):
        return self.ts.types[name]

    def header(self, t, frame=""):
        ns = round(t * 1e9)
        stamp = self.T("builtin_interfaces/msg/Time")(sec=ns // 10**9, nanosec=ns % 10**9)
        H = self.T("std_msgs/msg/Header")
        return H(seq=0, stamp=stamp, frame_id=frame) if self.ros1 else H(stamp=stamp,
                                                                         frame_id=frame)

    def write(self, topic, t, msg):
        kind = msg.__msgtype__
        if topic not in self.conns:
            self.conns[topic] = self.w.add_connection(topic, kind, typestore=self.ts)
        data = (self.ts.serialize_ros1 if self.ros1 else self.ts.serialize_cdr)(msg, kind)
        self.w.write(self.conns[topic], round(t * 1e9) + 1000, data)

    def joints(self, t, names, q):
        e = np.zeros(0)
        self.write("/joint_states", t, self.T("sensor_msgs/msg/JointState")(
            header=self.header(t), name=list(names), position=np.asarray(q, float),
            velocity=e, effort=e))

    def point(self, topic, t, xyz):
        P = self.T("geometry_msgs/msg/Point")
        self.write(topic, t, self.T("geometry_msgs/msg/PointStamped")(
            header=self.header(t, "tracker"), point=P(x=xyz[0], y=xyz[1], z=xyz[2])))

    def tf(self, topic, t, parent, child, T):
        pq = pq_from_transform(T)
        V, Q = self.T("geometry_msgs/msg/Vector3"), self.T("geometry_msgs/msg/Quaternion")
        tr = self.T("geometry_msgs/msg/Transform")(
            translation=V(x=pq[0], y=pq[1], z=pq[2]), rotation=Q(x=pq[4], y=pq[5], z=pq[6],
                                                                 w=pq[3]))
        ts = self.T("geometry_msgs/msg/TransformStamped")(
            header=self.header(t, parent), child_frame_id=child, transform=tr)
        self.write(topic, t, self.T("tf2_msgs/msg/TFMessage")(transforms=[ts]))

    def image(self, t, img):
        h, w = img.shape
        self.write("/camera/image_raw", t, self.T("sensor_msgs/msg/Image")(
            header=self.header(t, "camera"), height=h, width=w, encoding="mono8",
            is_bigendian=0, step=w, data=np.ascontiguousarray(img, np.uint8).ravel()))

    def camera_info(self, t, K, D, size):
        names = {"d": D, "k": K.ravel(), "r": np.eye(3).ravel(),
                 "p": np.c_[K, np.zeros(3)].ravel()}
        if self.ros1:
            names = {k.upper(): v for k, v in names.items()}
        roi = self.T("sensor_msgs/msg/RegionOfInterest")(x_offset=0, y_offset=0, height=0,
                                                         width=0, do_rectify=False)
        self.write("/camera/camera_info", t, self.T("sensor_msgs/msg/CameraInfo")(
            header=self.header(t, "camera"), height=size[1], width=size[0],
            distortion_model="plumb_bob", binning_x=0, binning_y=0, roi=roi,
            **{k: np.asarray(v, float) for k, v in names.items()}))

    def close(self):
        self.w.close()


def timeline(stations, rng_pause=True):
    """Times and joints (rad) at RATE: dwell DWELL at each station, smooth moves between,
    with a 0.25 s pause half-way through the move after station 3 (a short stop)."""
    t, q, windows = [], [], []
    now = 0.0
    dt = 1.0 / RATE
    for k, qk in enumerate(stations):
        n = round(DWELL * RATE)
        windows.append((now, now + (n - 1) * dt))
        for _ in range(n):
            t.append(now)
            q.append(qk)
            now += dt
        if k + 1 == len(stations):
            break
        a, b = qk, stations[k + 1]
        legs = [(a, (a + b) / 2), ((a + b) / 2, b)] if (k == 3 and rng_pause) else [(a, b)]
        for i, (qa, qb) in enumerate(legs):
            m = round(MOVE * RATE / len(legs))
            for j in range(1, m + 1):
                s = j / m
                t.append(now)
                q.append(qa + (qb - qa) * (3 * s**2 - 2 * s**3))
                now += dt
            if i == 0 and len(legs) == 2:
                for _ in range(round(0.25 * RATE)):
                    t.append(now)
                    q.append(qb)
                    now += dt
    return np.array(t), np.array(q), windows


@pytest.fixture(scope="module")
def session():
    model = load_model("ur5")
    rng = np.random.default_rng(7)
    stations = rng.uniform(-2.5, 2.5, (7, 6))
    t, q, windows = timeline(stations)
    xyz = model.positions(stations)  # mm, tracker frame = the model's measurement frame
    return model, stations, t, q, windows, xyz


def write_session(path, kind, session, tracker=True):
    _model, _stations, t, q, windows, xyz = session
    w = BagWriter(path, kind)
    order = [1, 2, 3, 4, 5, 0]  # UR2_NAMES in the arm's joint indices
    for ti, qi in zip(t, q, strict=True):
        w.joints(ti, UR2_NAMES, qi[order])
    for k, (a, b) in enumerate(windows):
        if not tracker or k == MISSING:
            continue
        stop = a + 0.3 * (b - a) if k == PARTIAL else b
        for ti in np.arange(a, stop + 1e-9, 0.01):  # 100 Hz, metres
            w.point("/tracker/point", ti, xyz[k] / 1000.0)
    w.close()
    return path


@pytest.mark.parametrize("kind", ["sqlite3", "mcap", "ros1"])
def test_import_gives_exactly_the_dwell_rows(tmp_path, capsys, session, kind):
    _model, stations, *_, xyz = session
    bag = write_session(tmp_path / ("rec.bag" if kind == "ros1" else "rec"), kind, session)
    out = tmp_path / "rows.csv"
    assert main(["import", str(bag), "--model", "ur5", "--joints", "/joint_states",
                 "--points", "/tracker/point", "--dwell", "0.3", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    keep = [k for k in range(len(stations)) if k not in (PARTIAL, MISSING)]
    assert "7 dwells found" in err and f"{len(keep)} kept, 2 dropped" in err
    assert "mapped by UR joint names" in err
    assert f"dropped dwell {MISSING + 1} " in err and "no /tracker/point message" in err
    assert f"dropped dwell {PARTIAL + 1} " in err and "partial: /tracker/point silent" in err
    assert "1 shorter stops ignored" in err and "short stop at" in err
    cols = [f"q{i}" for i in range(1, 7)] + ["x", "y", "z"]
    table = read_table(out, cols)
    rows = np.column_stack([table[c] for c in cols])
    assert rows.shape == (len(keep), 9)
    np.testing.assert_allclose(rows[:, :6], np.degrees(stations[keep]), rtol=0, atol=1e-6)
    np.testing.assert_allclose(rows[:, 6:], xyz[keep], rtol=0, atol=1e-6)


def test_joints_only_rows_and_joint_names(tmp_path, capsys, session):
    """Without a measurement topic the rows are the dwells' joints; --joint-names maps by
    name (here in the arm's order)."""
    stations = session[1]
    bag = write_session(tmp_path / "rec.mcap", "mcap", session, tracker=False)
    out = tmp_path / "joints.csv"
    names = "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint," \
            "wrist_2_joint,wrist_3_joint"
    assert main(["import", str(bag), "--model", "ur5", "--joints", "/joint_states",
                 "--joint-names", names, "--out", str(out)]) == 0
    assert "mapped by name" in capsys.readouterr().err
    table = read_table(out, [f"q{i}" for i in range(1, 7)])
    rows = np.column_stack([table[f"q{i}"] for i in range(1, 7)])
    np.testing.assert_allclose(rows, np.degrees(stations), rtol=0, atol=1e-6)


def test_dwell_finder_streams_in_chunks():
    """Chunk boundaries change nothing, and a slow start or end of a move (smoothstep,
    speed zero at its ends) does not leak into a dwell's mean."""
    stations = np.random.default_rng(1).uniform(-1, 1, (5, 2))
    t, q, windows = timeline(stations, rng_pause=False)
    found = []
    for chunk in (7, 100, 10_000):
        f = DwellFinder(2, 0.3, 0.002)
        for s in range(0, len(t), chunk):
            f.feed(t[s:s + chunk], q[s:s + chunk])
        found.append(f.finish())
    for dw in found:
        assert len(dw) == 5
        np.testing.assert_array_equal([d.samples for d in dw], [d.samples for d in found[0]])
        np.testing.assert_allclose([d.q for d in dw], stations, rtol=0, atol=1e-12)
        for d, (a, b) in zip(dw, windows, strict=True):
            assert a <= d.start and d.end <= b and d.span > 0.3


def test_tf_path_composes_averaged_edges():
    rng = np.random.default_rng(3)
    poses = [transform_from_pq(np.r_[rng.normal(size=3), q / np.linalg.norm(q)])
             for q in rng.normal(size=(3, 4))]
    tree = TfTree(np.array([0.0]), np.array([1.0]))
    tree.add("world", "base", None, 0.0, pq_from_transform(poses[0]), static=True)
    for ti in np.linspace(0.1, 0.9, 5):
        tree.add("base", "wrist", 0, ti, pq_from_transform(poses[1]), static=False)
        tree.add("cam", "wrist", 0, ti, pq_from_transform(poses[2]), static=False)
    T, why = tree.lookup(tree.path("world", "cam"), 0)
    assert why is None
    np.testing.assert_allclose(T, poses[0] @ poses[1] @ np.linalg.inv(poses[2]), atol=1e-12)


def _truncate(bag):
    """The bag with its data file cut to 60 % (the file inside a ROS 2 bag folder)."""
    f = bag if bag.is_file() else next(p for p in bag.iterdir() if p.suffix in (".db3",
                                                                                ".mcap"))
    data = f.read_bytes()
    f.write_bytes(data[: int(len(data) * 0.6)])
    return bag


@pytest.mark.parametrize(("case", "expected"), [
    ("no-topic", "topic '/tracker/nothing' is not in the bag"),
    ("names", "match no model joint"),
    ("truncated-sqlite3", "cannot read the bag"),
    ("truncated-mcap", "cannot read the bag"),
    ("truncated-ros1", "cannot read the bag"),
    ("wrong-type", "has type sensor_msgs/msg/JointState; --points takes"),
])
def test_bad_bags_exit_2_with_the_reason_and_write_nothing(tmp_path, capsys, session, case,
                                                           expected):
    kind = case.rsplit("-", 1)[1] if case.startswith("truncated") else "sqlite3"
    bag = write_session(tmp_path / ("rec.bag" if kind == "ros1" else "rec"), kind, session)
    args = ["import", str(bag), "--model", "ur5", "--joints", "/joint_states", "--points",
            "/tracker/point"]
    if case == "no-topic":
        args[-1] = "/tracker/nothing"
    elif case == "names":
        args += ["--joint-names", "a,b,c,d,e,f"]
    elif case == "wrong-type":
        args[-1] = "/joint_states"
    else:
        _truncate(bag)
    out = tmp_path / "rows.csv"
    assert main(args + ["--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_missing_extra_is_named(tmp_path, capsys, session, monkeypatch):
    bag = write_session(tmp_path / "rec", "sqlite3", session)
    monkeypatch.setitem(__import__("sys").modules, "rosbags.highlevel", None)
    out = tmp_path / "rows.csv"
    assert main(["import", str(bag), "--model", "ur5", "--joints", "/joint_states",
                 "--out", str(out)]) == 2
    assert "pip install kinecal[ros]" in capsys.readouterr().err and not out.exists()


def test_images_to_a_folder_handeye_images_reads(tmp_path, capsys):
    """Images and camera_info of the dwells become a folder: handeye-images on it finds the
    true X; robot poses come from /tf (--tf) or, without it, from the model's flange."""
    from kinecal.calibration.handeye.errors import pose_error
    from kinecal.vision.boards import parse_board
    from kinecal.vision.render import ImageConditions, render_handeye_scene

    K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
    D = np.array([-0.12, 0.04, 0.0005, -0.0003, 0.0])
    sc = render_handeye_scene(parse_board("chessboard:9x6:20"), K, D, (480, 360), 6,
                              conditions=ImageConditions(blur=0.7, noise=2.0), seed=3,
                              supersample=2)
    stations = np.random.default_rng(2).uniform(-2.0, 2.0, (6, 6))
    t, q, windows = timeline(stations, rng_pause=False)
    w = BagWriter(tmp_path / "he", "mcap")
    w.camera_info(0.0, K, D, (480, 360))
    for ti, qi in zip(t, q, strict=True):
        w.joints(ti, UR2_NAMES, qi[[1, 2, 3, 4, 5, 0]])
    for k, (a, b) in enumerate(windows):
        F = sc.flange2base[k].copy()
        F[:3, 3] /= 1000.0
        for ti in np.arange(a, b + 1e-9, 0.02):
            w.tf("/tf", ti, "base", "tool0", F)
        for ti in np.arange(a, b + 1e-9, 0.1):  # 10 Hz camera
            w.image(ti, sc.images[k])
    w.close()
    out = tmp_path / "stations"
    assert main(["import", str(tmp_path / "he"), "--model", "ur5", "--joints",
                 "/joint_states", "--tf", "base:tool0", "--images", "/camera/image_raw",
                 "--camera-info", "/camera/camera_info", "--out", str(out)]) == 0
    assert "6 kept, 0 dropped" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["camera.yaml", "measurements.csv", "robot_poses.csv", "stations.csv"]
        + [f"dwell_{k:03d}.png" for k in range(1, 7)])
    res = tmp_path / "he.json"
    assert main(["handeye-images", str(out), str(out / "robot_poses.csv"), "--board",
                 "chessboard:9x6:20", "--intrinsics", str(out / "camera.yaml"), "--quiet",
                 "--out", str(res)]) == 0
    import json

    X = np.array(json.loads(res.read_text())["X"])
    rot, tr = pose_error(X, sc.X)
    assert rot < 0.05 and tr < 0.2  # deg, mm
    # without --tf: the robot poses are the model's flange at the dwell joints
    out2 = tmp_path / "fk"
    assert main(["import", str(tmp_path / "he"), "--model", "ur5", "--joints",
                 "/joint_states", "--images", "/camera/image_raw", "--camera-info",
                 "/camera/camera_info", "--out", str(out2)]) == 0
    cols = ["flange_x", "flange_y", "flange_z", "flange_qw", "flange_qx", "flange_qy",
            "flange_qz"]
    table = read_table(out2 / "robot_poses.csv", cols)
    pq = np.column_stack([table[c] for c in cols])
    model = load_model("ur5")
    p = model.nominal
    p[model.index(["tool.x", "tool.y", "tool.z"])] = 0.0
    np.testing.assert_allclose(pq, pq_from_transform(model.fk(stations, p)), atol=1e-9)
