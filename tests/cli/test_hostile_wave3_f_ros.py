"""Hostile-input sweep, wave 3: ``kinecal import`` (ROS bags, UR calibration.conf),
``kinecal export`` (ur-kinematics, ros-tf, urdf --camera) and their Python API.

The contract (tests/cli/test_hostile_issue28.py): exit 2 with one ``kinecal: error:`` line
naming the file or option and the reason, nothing written; or exit 0 with a ``kinecal:
warning: ... [CODE]`` line where the input is implausible; never an exit 1 or a silent
wrong answer. Bags are written here with rosbags (ROS 2, sqlite3): a UR5 at 50 Hz
dwelling 0.6 s at three stations, a tracker's points at 50 Hz while it dwells.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Writer
from rosbags.typesys import Stores, get_typestore

import kinecal
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.csvtable import read_table
from kinecal.io.models import load_model
from kinecal.io.ros.importer import ImportOptions, import_bag
from kinecal.io.ros.static_tf import static_transform
from kinecal.io.ur.kinematics import ur_kinematics
from kinecal.io.ur.robots import nominal_dh, ur_model

TS = get_typestore(Stores.ROS2_HUMBLE)
UR = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
      "wrist_2_joint", "wrist_3_joint"]
STATIONS = np.random.default_rng(4).uniform(-2.0, 2.0, (3, 6))  # rad
XYZ = load_model("ur5").positions(STATIONS) / 1000.0  # m, as a tracker publishes
_WARNING = re.compile(r"^kinecal: warning: .+ \[([a-z0-9-]+)\]$")


def M(kind: str, **fields):
    return TS.types[kind](**fields)


def header(t: float, frame: str = ""):
    ns = round(t * 1e9)
    return M("std_msgs/msg/Header", stamp=M("builtin_interfaces/msg/Time", sec=ns // 10**9,
                                              nanosec=ns % 10**9), frame_id=frame)


def timeline() -> list[tuple[float, np.ndarray, int | None]]:
    """(time, joints, dwell index or None while moving) at 50 Hz."""
    out, now = [], 0.0
    for k, q in enumerate(STATIONS):
        out += [(now + i / 50, q, k) for i in range(30)]
        now += 0.6
        if k + 1 < len(STATIONS):
            nxt = STATIONS[k + 1]
            out += [(now + i / 50, q + (nxt - q) * (i / 30), None) for i in range(1, 31)]
            now += 0.62
    return out


def write_bag(path: Path, names=UR, joints=None, point=None, pose=None, image=None,
              info_k=None, tf=None) -> Path:
    """A session bag; each callable maps (sample index, t, value) to what is published
    (None: nothing)."""
    conns = {}

    def put(w, topic, kind, t, msg):
        if topic not in conns:
            conns[topic] = w.add_connection(topic, kind, typestore=TS)
        w.write(conns[topic], round(t * 1e9), TS.serialize_cdr(msg, kind))

    with Writer(path, version=9) as w:
        if info_k is not None:
            K = np.asarray(info_k, float)
            put(w, "/camera/camera_info", "sensor_msgs/msg/CameraInfo", 0.0, M(
                "sensor_msgs/msg/CameraInfo", header=header(0.0), height=48, width=64,
                distortion_model="plumb_bob", d=np.zeros(5), k=K.ravel(), r=np.eye(3).ravel(),
                p=np.c_[K, np.zeros(3)].ravel(), binning_x=0, binning_y=0,
                roi=M("sensor_msgs/msg/RegionOfInterest", x_offset=0, y_offset=0, height=0,
                      width=0, do_rectify=False)))
        for i, (t, q, k) in enumerate(timeline()):
            pos = q if joints is None else joints(i, t, q)
            put(w, "/joint_states", "sensor_msgs/msg/JointState", t, M(
                "sensor_msgs/msg/JointState", header=header(t), name=list(names),
                position=np.asarray(pos, float), velocity=np.zeros(0), effort=np.zeros(0)))
            if k is None:
                continue
            p = XYZ[k] if point is None else point(i, t, XYZ[k])
            put(w, "/tracker/point", "geometry_msgs/msg/PointStamped", t, M(
                "geometry_msgs/msg/PointStamped", header=header(t),
                point=M("geometry_msgs/msg/Point", x=p[0], y=p[1], z=p[2])))
            if pose is not None:
                qw, qx, qy, qz = pose
                put(w, "/tracker/pose", "geometry_msgs/msg/PoseStamped", t, M(
                    "geometry_msgs/msg/PoseStamped", header=header(t), pose=M(
                        "geometry_msgs/msg/Pose",
                        position=M("geometry_msgs/msg/Point", x=p[0], y=p[1], z=p[2]),
                        orientation=M("geometry_msgs/msg/Quaternion", x=qx, y=qy, z=qz,
                                      w=qw))))
            if image is not None and i % 5 == 0:
                put(w, "/camera/image_raw", *image(t))
    return path


def run(argv, capsys):
    """Exit status, warning codes, error lines (and nothing else but progress)."""
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert not any("Traceback" in line or "internal error" in line for line in lines), err
    codes = [m.group(1) for m in map(_WARNING.match, lines) if m]
    errors = [line for line in lines if line.startswith("kinecal: error: ")]
    return code, codes, errors


def imp(bag: Path, out: Path, *extra) -> list[str]:
    return ["import", bag, "--model", "ur5", "--joints", "/joint_states", *extra, "--out", out]


def rows(out: Path) -> np.ndarray:
    cols = [f"q{i}" for i in range(1, 7)] + ["x", "y", "z"]
    t = read_table(out, cols)
    return np.column_stack([t[c] for c in cols])


def refused(code, errors, out: Path, *words: str) -> None:
    assert code == 2 and len(errors) == 1, errors
    assert all(w in errors[0] for w in words), errors[0]
    assert not out.exists()


# ---- bags


def test_metadata_without_keys_is_named_without_an_exception_repr(tmp_path, capsys):
    bag = write_bag(tmp_path / "rec")
    meta = bag / "metadata.yaml"
    meta.write_text(meta.read_text().replace("version:", "versio:"))
    out = tmp_path / "rows.csv"
    code, _, errors = run(imp(bag, out), capsys)
    refused(code, errors, out, "cannot read the bag", "'version'")
    assert "KeyError" not in errors[0]


def test_output_onto_the_metadata_of_the_bag_read_through_its_db3_is_refused(tmp_path,
                                                                             capsys):
    """BAG given as the .db3 inside a bag folder: metadata.yaml beside it is part of the
    bag (was overwritten by the rows)."""
    bag = write_bag(tmp_path / "rec")
    meta = (bag / "metadata.yaml").read_bytes()
    code, _, errors = run(imp(next(bag.glob("*.db3")), bag / "metadata.yaml"), capsys)
    assert code == 2 and "inside the input folder BAG" in errors[0]
    assert (bag / "metadata.yaml").read_bytes() == meta


def test_repeated_joint_names_are_refused_not_mapped_onto_one_position(tmp_path, capsys):
    bag = write_bag(tmp_path / "rec", names=["shoulder_pan_joint"] * 6)
    out = tmp_path / "rows.csv"
    code, _, errors = run(imp(bag, out, "--points", "/tracker/point"), capsys)
    refused(code, errors, out, "--joints", "shoulder_pan_joint more than once")
    good = write_bag(tmp_path / "good")
    names = ",".join(["shoulder_pan_joint", *UR[:5]])
    code, _, errors = run(imp(good, out, "--joint-names", names), capsys)
    refused(code, errors, out, "--joint-names", "shoulder_pan_joint given twice")


def test_non_finite_joint_samples_are_left_out_with_a_warning(tmp_path, capsys):
    """Every 7th JointState NaN: the dwells are found in the others (before: none at all)."""
    bag = write_bag(tmp_path / "rec", joints=lambda i, t, q: q * np.nan if i % 7 == 0 else q)
    out = tmp_path / "rows.csv"
    code, codes, _ = run(imp(bag, out, "--points", "/tracker/point"), capsys)
    assert code == 0 and codes == ["ros-samples-skipped"]
    np.testing.assert_allclose(rows(out)[:, :6], np.degrees(STATIONS), atol=1e-9)


def test_positions_fewer_than_names_are_named_as_such(tmp_path, capsys):
    """Was: 'topic /joint_states has no message' for a topic of 150 messages."""
    bag = write_bag(tmp_path / "rec", joints=lambda i, t, q: q[:4])
    out = tmp_path / "rows.csv"
    code, _, errors = run(imp(bag, out), capsys)
    refused(code, errors, out, "no JointState (150) has as many positions as names",
            "6 names and 4 positions")


def test_nan_points_are_left_out_not_averaged_into_the_rows(tmp_path, capsys):
    bag = write_bag(tmp_path / "some", point=lambda i, t, p: p * np.nan if i % 4 == 0 else p)
    out = tmp_path / "rows.csv"
    code, codes, _ = run(imp(bag, out, "--points", "/tracker/point"), capsys)
    assert code == 0 and codes == ["ros-bad-values"]
    np.testing.assert_allclose(rows(out)[:, 6:], XYZ * 1000.0, atol=1e-9)
    every = write_bag(tmp_path / "every", point=lambda i, t, p: p * np.inf)
    out2 = tmp_path / "rows2.csv"
    code, codes, errors = run(imp(every, out2, "--points", "/tracker/point"), capsys)
    assert codes == ["ros-bad-values"]
    refused(code, errors, out2, str(every), "none of the 3 dwells could be kept")


def test_unset_pose_quaternion_is_no_measurement(tmp_path, capsys):
    bag = write_bag(tmp_path / "rec", pose=(0.0, 0.0, 0.0, 0.0))
    out = tmp_path / "rows.csv"
    code, codes, errors = run(imp(bag, out, "--poses", "/tracker/pose"), capsys)
    assert codes == ["ros-bad-values"]
    refused(code, errors, out, "no /tracker/pose message during the dwell")


def test_joints_in_degrees_warn(tmp_path, capsys):
    bag = write_bag(tmp_path / "rec", joints=lambda i, t, q: np.degrees(q))
    out = tmp_path / "rows.csv"
    code, codes, _ = run(imp(bag, out, "--points", "/tracker/point"), capsys)
    assert code == 0 and codes == ["ros-joint-units"]


def test_tf_of_a_frame_in_itself_is_refused(tmp_path, capsys):
    out = tmp_path / "rows.csv"
    code, _, errors = run(imp(write_bag(tmp_path / "rec"), out, "--tf", "base:/base"), capsys)
    refused(code, errors, out, "--tf", "expected two frames")


def _mono(t, h=48, w=64, enc="mono8"):
    return ("sensor_msgs/msg/Image", t, M("sensor_msgs/msg/Image", header=header(t), height=h,
                                          width=w, encoding=enc, is_bigendian=0, step=w,
                                          data=np.full(h * w, 128, np.uint8)))


K_GOOD = [[70.0, 0, 31.5], [0, 70.0, 23.5], [0, 0, 1]]
IMAGES = ["--images", "/camera/image_raw", "--camera-info", "/camera/camera_info"]


@pytest.mark.parametrize(("case", "words"), [
    ("zero-size", ("--images", "0 x 0 pixels")),  # was exit 1 (reshape error)
    ("fake-png", ("--images", "starts like a PNG")),
    ("uncalibrated", ("--camera-info", "no CameraInfo of a calibrated camera")),
])
def test_images_that_are_none_are_refused_and_no_folder_is_left(tmp_path, capsys, case,
                                                                words):
    image, k = (lambda t: _mono(t)), K_GOOD
    if case == "zero-size":
        image = lambda t: _mono(t, 0, 0)  # noqa: E731
    elif case == "fake-png":
        image = lambda t: ("sensor_msgs/msg/CompressedImage", t, M(  # noqa: E731
            "sensor_msgs/msg/CompressedImage", header=header(t), format="png",
            data=np.frombuffer(b"\x89PNG" + bytes(20), np.uint8)))
    else:
        k = np.zeros((3, 3))  # ROS's uncalibrated camera
    bag = write_bag(tmp_path / "rec", image=image, info_k=k)
    out = tmp_path / "stations"
    code, _, errors = run(imp(bag, out, *IMAGES), capsys)
    refused(code, errors, out, *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec"]


# ---- calibration.conf

#: a UR5's file as a controller writes it (made in tests/io/test_ur_calibration_files.py:
#: the exact D-H table of a UR5 with small link errors; the flange 1.6 mm from nominal)
CONF = """[mounting]
delta_theta = [ 0.0006798841118, -0.09710428905, -0.1001883061, 0.1984317472, -2.836796251e-05, 0.0002148257605 ]
delta_a = [ -0.0001529845196, 0.001430047497, 0.007772780593, -0.0004542460468, -0.0003579562423, 0 ]
delta_d = [ -8.939349411e-05, -143.4112634, -78.49640144, 221.9075546, 0.0002464243471, -5.880265182e-05 ]
delta_alpha = [ 1.668005261e-05, 0.0002862391237, 0.0003469744957, -7.624388422e-05, -0.0009602654312, 0 ]
"""  # noqa: E501


@pytest.mark.parametrize(("text", "expected"), [
    (CONF.replace("0.0006798841118", "1e300"),
     "error: delta_theta: 1e+300 is beyond 4096 rad"),
    # lengths in mm: the flange moves kilometres (was refused on the size of one delta)
    (CONF.replace("-0.0001529845196, 0.001430047497, 0.007772780593", "-0.15, 1.43, 7.77"),
     "error: more than the arm's reach"),
    (CONF.replace("0.0006798841118, -0.09710428905", "0.0006798841118, -0.04710428905"),
     "ur-conf-implausible"),  # 0.05 rad off on joint 2: the flange moves centimetres
    (CONF.replace("-143.4112634", "-143.2112634"), "ur-conf-implausible"),
    ("\ufeff" + CONF, "clean"),  # a byte-order mark: was 'no [mounting] section'
])
def test_calibration_conf_ranges(tmp_path, capsys, text, expected):
    conf = tmp_path / "calibration.conf"
    conf.write_text(text, encoding="utf-8")
    out = tmp_path / "model.yaml"
    code, codes, errors = run(["import", conf, "--robot", "ur5", "--out", out], capsys)
    if expected.startswith("error: "):
        refused(code, errors, out, expected[len("error: "):])
    else:
        assert code == 0 and out.exists()
        assert codes == ([] if expected == "clean" else [expected])


# ---- export


@pytest.fixture(scope="module")
def handeye(tmp_path_factory) -> Path:
    """A hand-eye result in mm: the camera 70 mm off the flange."""
    X = np.eye(4)
    X[:3, 3] = (70.0, -20.0, 60.0)
    path = tmp_path_factory.mktemp("he") / "he.json"
    path.write_text(json.dumps({"X": X.tolist(), "setup": "eye-in-hand",
                                "length_unit": "mm"}))
    return path


def test_json_with_an_overlong_integer_is_an_input_error(tmp_path, capsys, handeye):
    """Was exit 1 (Python's integer-digit limit)."""
    bad = tmp_path / "result.json"
    bad.write_text('{"model": "ur5", "seed": 1' + "0" * 5000 + "}")
    for argv in (["export", bad, "--format", "ur-kinematics"],
                 ["export", bad, "--format", "ros-tf", "--unit", "mm"],
                 ["export", "ur5", "--format", "urdf", "--camera", bad, "--unit", "mm"]):
        out = tmp_path / "out.yaml"
        code, _, errors = run([*argv, "--out", out], capsys)
        refused(code, errors, out, str(bad), "not valid JSON")


def test_ur_kinematics_of_a_non_ur_model_warns_and_empty_robot_is_refused(tmp_path, capsys):
    out = tmp_path / "k.yaml"
    code, codes, _ = run(["export", "puma560", "--format", "ur-kinematics", "--out", out],
                         capsys)
    assert code == 0 and codes == ["ur-kinematics-not-ur"]
    code, codes, _ = run(["export", "ur5", "--format", "ur-kinematics", "--out",
                          tmp_path / "u.yaml"], capsys)
    assert code == 0 and codes == []
    out2 = tmp_path / "e.yaml"
    code, _, errors = run(["export", "ur5", "--format", "ur-kinematics", "--robot", "",
                           "--out", out2], capsys)
    refused(code, errors, out2, "--robot", "unknown robot ''")


@pytest.mark.parametrize("fmt", ["ros-tf", "urdf"])
def test_camera_frames_and_distance(tmp_path, capsys, handeye, fmt):
    source = [handeye] if fmt == "ros-tf" else ["ur5", "--camera", handeye]
    ext = ".launch.py" if fmt == "ros-tf" else ".urdf"
    for opt, name in (("--child-frame", "a b"), ("--parent-frame", " "),
                      ("--child-frame", "")):
        out = tmp_path / f"x{ext}"
        code, _, errors = run(["export", *source, "--format", fmt, "--unit", "mm", opt, name,
                               "--out", out], capsys)
        refused(code, errors, out, opt, "expected a frame name without spaces")
    # a mm result read as metres: the camera 95 m off the flange
    out = tmp_path / f"far{ext}"
    code, codes, _ = run(["export", *source, "--format", fmt, "--unit", "m", "--out", out],
                         capsys)
    assert code == 0 and codes == ["camera-mount-far"]
    code, codes, _ = run(["export", *source, "--format", fmt, "--unit", "mm", "--out",
                          tmp_path / f"ok{ext}"], capsys)
    assert code == 0 and codes == []


# ---- Python API


def test_python_api_raises_input_error_or_type_error(tmp_path):
    ur5 = load_model("ur5")
    with pytest.raises(InputError, match="positive time"):
        ImportOptions("/joint_states", dwell=-1.0)
    with pytest.raises(InputError, match="two frames"):
        ImportOptions("/joint_states", tf=("base", "base"))
    bag = write_bag(tmp_path / "rec")
    with pytest.raises(InputError, match="expected 6 names"):
        import_bag(bag, ur5, ImportOptions("/joint_states", joint_names=["a"]))
    with pytest.raises(TypeError):
        import_bag(bag, None, ImportOptions("/joint_states"))
    with pytest.raises(TypeError):
        nominal_dh(5)
    with pytest.raises(InputError, match=r"\(6, 4\)"):
        ur_model("ur5", np.zeros((5, 4)))
    with pytest.raises(InputError, match="finite parameter values"):
        ur_kinematics(ur5, np.zeros(3))
    with pytest.raises(InputError, match="finite parameter values"):
        ur_kinematics(ur5, np.full(ur5.nominal.size, np.nan))
    with pytest.raises(InputError, match="setup"):
        static_transform(np.eye(4), "eye-on-hand", 1.0)
    with pytest.raises(InputError, match="4x4"):
        static_transform(np.eye(3), "eye-in-hand", 1.0)
    assert kinecal.InputError is InputError
