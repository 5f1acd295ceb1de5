"""Importing a large ROS 2 bag: kinecal import against a plain rosbags read of the same
topics, with peak memory.

A bag of about 1 GB (``--size-gb``) is written once with rosbags (mcap by default,
``--storage sqlite3``): a UR5's ``/joint_states`` at 500 Hz (the ROS driver's rate), a
tracker's ``/tracker/point`` at 100 Hz during dwells of 2 s between 2 s moves, and a
640 x 480 mono8 camera at 15 Hz throughout (the bulk of the bytes), with camera_info.
Then, alternately and each in a fresh process:

* ``kinecal import BAG --joints ... --points ... --out rows.csv`` (in-process call of the
  CLI), the rows of the dwells;
* ``kinecal import ... --images ... --camera-info ... --out DIR``: also one PNG per dwell;
* the peer: what a user's script does with rosbags alone (``AnyReader``, deserializing
  every message on the joint and point topics, collecting the joints and points in lists:
  no dwell finding, no averaging, nothing written); with images, deserializing every
  image too but keeping none.

Printed: wall time and peak resident memory (``VmHWM``) of each, and the ratio of the
times (kinecal / peer). Memory is bounded when it does not grow with the bag: run with
``--size-gb 0.25`` and ``1`` to compare.

Run: ``python benchmarks/bench_import.py [--quick] [--size-gb G] [--repeat R]``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

JOINT_HZ, POINT_HZ, IMAGE_HZ = 500, 100, 15
DWELL_S, MOVE_S = 2.0, 2.0
W, H = 640, 480


def _peak_bytes() -> int:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _joints(t: np.ndarray, stations: np.ndarray) -> np.ndarray:
    """Joints at times `t`: dwell, smooth move, dwell, ... over `stations`."""
    period = DWELL_S + MOVE_S
    k = np.minimum((t // period).astype(int), len(stations) - 2)
    s = np.clip((t - k * period - DWELL_S) / MOVE_S, 0.0, 1.0)[:, None]
    a, b = stations[k], stations[k + 1]
    return a + (b - a) * (3 * s**2 - 2 * s**3)


def write_bag(path: Path, size_gb: float, storage: str) -> dict:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    duration = size_gb * 1e9 / (W * H * IMAGE_HZ)
    rng = np.random.default_rng(0)
    stations = rng.uniform(-2.5, 2.5, (int(duration / (DWELL_S + MOVE_S)) + 2, 6))
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    img = rng.integers(0, 255, (H, W), dtype=np.uint8).ravel()
    roi = T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                 do_rectify=False)
    K = np.array([600.0, 0, 319.5, 0, 600.0, 239.5, 0, 0, 1])

    def header(t):
        ns = round(t * 1e9)
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
            sec=ns // 10**9, nanosec=ns % 10**9), frame_id="")

    events = []  # (time, topic)
    events += [(t, "j") for t in np.arange(0, duration, 1 / JOINT_HZ)]
    events += [(t, "c") for t in np.arange(0, duration, 1 / IMAGE_HZ)]
    events += [(t, "p") for t in np.arange(0, duration, 1 / POINT_HZ)
               if t % (DWELL_S + MOVE_S) < DWELL_S]
    events.sort()
    e = np.zeros(0)
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {
            "j": w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts),
            "p": w.add_connection("/tracker/point", "geometry_msgs/msg/PointStamped",
                                  typestore=ts),
            "c": w.add_connection("/camera/image_raw", "sensor_msgs/msg/Image", typestore=ts),
            "i": w.add_connection("/camera/camera_info", "sensor_msgs/msg/CameraInfo",
                                  typestore=ts)}
        info = T["sensor_msgs/msg/CameraInfo"](
            header=header(0.0), height=H, width=W, distortion_model="plumb_bob", d=np.zeros(5),
            k=K, r=np.eye(3).ravel(), p=np.r_[K[:3], 0, K[3:6], 0, K[6:], 0], binning_x=0,
            binning_y=0, roi=roi)
        w.write(conns["i"], 1, ts.serialize_cdr(info, info.__msgtype__))
        for t, kind in events:
            if kind == "j":
                msg = T["sensor_msgs/msg/JointState"](header=header(t), name=names,
                                                      position=_joints(np.array([t]),
                                                                       stations)[0],
                                                      velocity=e, effort=e)
            elif kind == "p":
                p = T["geometry_msgs/msg/Point"](x=0.5, y=0.1, z=0.3)
                msg = T["geometry_msgs/msg/PointStamped"](header=header(t), point=p)
            else:
                msg = T["sensor_msgs/msg/Image"](header=header(t), height=H, width=W,
                                                 encoding="mono8", is_bigendian=0, step=W,
                                                 data=img)
            w.write(conns[kind], round(t * 1e9) + 1000, ts.serialize_cdr(msg, msg.__msgtype__))
    return {"seconds": duration, "stations": len(stations) - 1}


def child(kind: str, path: str, out: str) -> None:
    from kinecal.cli import main

    res = {"kind": kind, "base_bytes": _peak_bytes()}
    t0 = time.perf_counter()
    if kind.startswith("kinecal"):
        args = ["import", path, "--model", "ur5", "--joints", "/joint_states", "--points",
                "/tracker/point", "--out", out, "--quiet"]
        if kind == "kinecal-images":
            args += ["--images", "/camera/image_raw", "--camera-info", "/camera/camera_info"]
        assert main(args) == 0
        rows = (Path(out) / "measurements.csv" if kind == "kinecal-images" else Path(out))
        res["rows"] = len(rows.read_text().splitlines()) - 1
    else:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        topics = {"/joint_states", "/tracker/point"}
        if kind == "rosbags-images":
            topics.add("/camera/image_raw")
        q, p, n_img = [], [], 0
        with AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as r:
            conns = [c for c in r.connections if c.topic in topics]
            for con, _t, raw in r.messages(connections=conns):
                msg = r.deserialize(raw, con.msgtype)
                if con.topic == "/joint_states":
                    q.append(np.asarray(msg.position))
                elif con.topic == "/tracker/point":
                    p.append((msg.point.x, msg.point.y, msg.point.z))
                else:
                    n_img += 1
        res["rows"] = len(q)
    res["seconds"] = time.perf_counter() - t0
    res["peak_bytes"] = _peak_bytes()
    print(json.dumps(res))


def run(kind: str, path: Path, out: Path) -> dict:
    proc = subprocess.run([sys.executable, __file__, "--child", kind, str(path), str(out)],
                          capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a 0.1 GB bag, one run each")
    ap.add_argument("--size-gb", type=float, default=None)
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    size = args.size_gb or (0.1 if args.quick else 1.0)
    repeat = args.repeat or (1 if args.quick else 2)
    with tempfile.TemporaryDirectory(prefix="kinecal-bench-") as tmp:
        bag = Path(tmp) / "big"
        t0 = time.perf_counter()
        info = write_bag(bag, size, args.storage)
        nbytes = sum(f.stat().st_size for f in bag.iterdir())
        print(f"{args.storage} bag: {nbytes / 1e9:.2f} GB, {info['seconds']:.0f} s of "
              f"recording, {info['stations']} dwells (written in "
              f"{time.perf_counter() - t0:.0f} s)")
        kinds = ["kinecal", "rosbags", "kinecal-images", "rosbags-images"]
        runs: dict[str, list] = {k: [] for k in kinds}
        for r in range(repeat):
            for kind in kinds:
                out = Path(tmp) / f"out-{kind}-{r}" / ("rows.csv" if kind == "kinecal"
                                                     else "")
                out.parent.mkdir(exist_ok=True)
                runs[kind].append(run(kind, bag, out if kind == "kinecal" else
                                      Path(tmp) / f"dir-{kind}-{r}"))
        for kind in kinds:
            s = [x["seconds"] for x in runs[kind]]
            m = [x["peak_bytes"] / 1e6 for x in runs[kind]]
            base = [x["base_bytes"] / 1e6 for x in runs[kind]]
            print(f"  {kind:<16} {min(s):7.1f}-{max(s):7.1f} s  peak RSS {min(m):5.0f}-"
                  f"{max(m):5.0f} MB (at start {min(base):.0f} MB), rows "
                  f"{runs[kind][0]['rows']}")
        for a, b in (("kinecal", "rosbags"), ("kinecal-images", "rosbags-images")):
            ka = min(x["seconds"] for x in runs[a])
            kb = min(x["seconds"] for x in runs[b])
            print(f"  time {a} / {b}: {ka / kb:.2f}x")


if __name__ == "__main__":
    main()
