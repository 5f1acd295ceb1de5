"""Hand-eye inputs as they come: 4x4 matrices (CSV rows, OpenCV FileStorage lists),
base2gripper recordings, rotation vectors (UR), ZYX Euler A, B, C (KUKA), roll-pitch-yaw,
degrees or radians."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from kinecal import InputError
from kinecal.calibration.handeye import calibrate_handeye
from kinecal.calibration.handeye.poses import star_polygon_poses
from kinecal.cli import main
from kinecal.io.csvtable import write_table
from kinecal.io.handeye import read_handeye_files, read_handeye_pairs, write_handeye_csv
from kinecal.io.poses import PoseFormat, read_poses
from kinecal.spatial import (
    axis_angle_from_matrix,
    invert_transform,
    matrix_from_rpy,
    pq_from_transform,
    rpy_from_matrix,
    transform_from,
)

X_TRUE = transform_from(matrix_from_rpy([0.2, -0.1, 0.9]), [25.0, -15.0, 70.0])
Y_TRUE = transform_from(matrix_from_rpy([0.0, 0.0, 0.5]), [550.0, 80.0, 10.0])


def recording(noise: float = 0.0):
    """A base2gripper recording (as a robot controller logs it) and target2cam poses."""
    cam = star_polygon_poses(380.0, 80.0, 9)
    C = invert_transform(cam)
    F = Y_TRUE @ cam @ invert_transform(X_TRUE)
    if noise:
        rng = np.random.default_rng(0)
        C = C @ transform_from(matrix_from_rpy(rng.normal(0, noise, (9, 3))),
                               rng.normal(0, 10 * noise, (9, 3)))
    return invert_transform(F), C


def fs_write(path, lists: dict) -> None:
    """OpenCV FileStorage: lists of 4x4 matrices, as cv::FileStorage writes them."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    for key, mats in lists.items():
        fs.startWriteStruct(key, cv2.FileNode_SEQ)
        for M in mats:
            fs.write("", np.ascontiguousarray(M))
        fs.endWriteStruct()
    fs.release()


def matrix_rows(path, *stacks) -> None:
    rows = np.concatenate([s.reshape(len(s), 16) for s in stacks], axis=1)
    path.write_text("\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")


def solve(F, C):
    return calibrate_handeye(F, C, setup="eye-in-hand", method="park", refine="lm").X


def test_4x4_base2gripper_lists_equal_the_quaternion_route_bit_for_bit(tmp_path):
    B, C = recording(noise=1e-3)
    F = invert_transform(B)  # what the user would compute by hand for the quaternion CSV
    write_handeye_csv(tmp_path / "pairs.csv", F, C)
    X_quat = solve(*read_handeye_pairs(tmp_path / "pairs.csv"))
    assert np.abs(X_quat[:3, 3] - X_TRUE[:3, 3]).max() < 2.0  # noisy, but the right X
    # OpenCV FileStorage lists named by direction: base2gripper is inverted by its name
    fs_write(tmp_path / "lists.yml", {"base2gripper": B, "target2cam": C})
    X_fs = solve(*read_handeye_pairs(tmp_path / "lists.yml"))
    # 16 numbers per row, no header, in two files; --invert-robot says base2gripper
    matrix_rows(tmp_path / "robot.csv", B)
    matrix_rows(tmp_path / "cam.csv", C)
    X_rows = solve(*read_handeye_files(tmp_path / "robot.csv", tmp_path / "cam.csv",
                                       PoseFormat(invert=True), PoseFormat()))
    # 32 numbers per row: one pairs file
    matrix_rows(tmp_path / "both.csv", F, C)
    X_both = solve(*read_handeye_pairs(tmp_path / "both.csv"))
    for X in (X_fs, X_rows, X_both):
        assert np.array_equal(X, X_quat)


def test_bundled_recording_as_matrices_or_quaternions_gives_the_same_x(tmp_path):
    from kinecal.cli.handeye import resolve_pairs

    path, setup = resolve_pairs("handeye-camodocal")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)  # the matrices as stored
    n = int(fs.getNode("frameCount").real())
    F = np.stack([fs.getNode(f"T1_{i}").mat() for i in range(n)])
    C = np.stack([fs.getNode(f"T2_{i}").mat() for i in range(n)])
    write_handeye_csv(tmp_path / "camodocal.csv", F, C)  # their quaternions
    a = calibrate_handeye(*read_handeye_pairs(path), setup=setup, refine="none").X
    b = calibrate_handeye(*read_handeye_pairs(tmp_path / "camodocal.csv"), setup=setup,
                          refine="none").X
    assert np.array_equal(a, b)


@pytest.mark.parametrize(
    ("fmt", "columns", "convert"),
    [
        ("rotvec", ("rx", "ry", "rz"), lambda R: axis_angle_from_matrix(R)),  # UR, rad
        ("rotvec:deg", ("rx", "ry", "rz"), lambda R: np.degrees(axis_angle_from_matrix(R))),
        ("euler-zyx:deg", ("A", "B", "C"), lambda R: np.degrees(rpy_from_matrix(R)[:, ::-1])),
        ("auto:deg", ("A", "B", "C"), lambda R: np.degrees(rpy_from_matrix(R)[:, ::-1])),
        ("auto", ("roll", "pitch", "yaw"), lambda R: rpy_from_matrix(R)),
        ("matrix", None, None),
    ],
)
def test_robot_pose_formats(tmp_path, fmt, columns, convert):
    B, C = recording()
    F = invert_transform(B)
    robot = tmp_path / "robot.csv"
    if columns is None:
        write_table(robot, {f"m{i}{j}": F[:, i, j] for i in range(4) for j in range(4)})
    else:
        ang = convert(F[:, :3, :3])
        cols = {"X": F[:, 0, 3], "Y": F[:, 1, 3], "Z": F[:, 2, 3]}
        cols.update({c: ang[:, k] for k, c in enumerate(columns)})
        write_table(robot, cols)
    write_table(tmp_path / "cam.csv", dict(zip(("x", "y", "z", "qw", "qx", "qy", "qz"),
                                               pq_from_transform(C).T, strict=True)))
    F2 = read_poses(robot, PoseFormat.parse(fmt))
    np.testing.assert_allclose(F2, F, rtol=0, atol=1e-12)
    out = tmp_path / "x.json"
    assert main(["handeye", "--robot-poses", str(robot), "--robot-format", fmt,
                 "--target-poses", str(tmp_path / "cam.csv"), "--refine", "none",
                 "--out", str(out)]) == 0
    X = np.array(json.loads(out.read_text())["X"])
    np.testing.assert_allclose(X, X_TRUE, rtol=0, atol=1e-9)


def test_cli_invert_options_and_filestorage(tmp_path, capsys):
    B, C = recording()
    fs_write(tmp_path / "robot.yml", {"poses": B})
    fs_write(tmp_path / "cam.yml", {"poses": invert_transform(C)})
    out = tmp_path / "x.json"
    args = ["handeye", "--robot-poses", str(tmp_path / "robot.yml"), "--invert-robot",
            "--target-poses", str(tmp_path / "cam.yml"), "--invert-target", "--out", str(out)]
    assert main(args) == 0
    np.testing.assert_allclose(json.loads(out.read_text())["X"], X_TRUE, atol=1e-9)
    assert main(args[:3] + args[4:]) == 0  # without --invert-robot: a different, wrong X
    capsys.readouterr()
    assert np.abs(np.array(json.loads(out.read_text())["X"]) - X_TRUE).max() > 1.0


@pytest.mark.parametrize(
    ("write", "kwargs", "match"),
    [
        (lambda p, B, C: write_table(p, {"x": B[:, 0, 3], "y": B[:, 1, 3], "z": B[:, 2, 3],
                                         "rx": B[:, 0, 0], "ry": B[:, 0, 1], "rz": B[:, 0, 2]}),
         {}, "rotation vector .* or fixed-axis angles"),
        (lambda p, B, C: matrix_rows(p, B.transpose(0, 2, 1)), {}, "last row"),
        (lambda p, B, C: matrix_rows(p, B * [[1.01], [1], [1], [1]]), {}, "orthonormal"),
        (lambda p, B, C: matrix_rows(p, B), {"fmt": PoseFormat("rpy")}, "no header"),
        (lambda p, B, C: p.write_text("1,2,3\n"), {}, "3 numbers per row"),
    ],
)
def test_pose_file_errors(tmp_path, write, kwargs, match):
    B, C = recording()
    path = tmp_path / "robot.csv"
    write(path, B, C)
    with pytest.raises(InputError, match=match) as info:
        read_poses(path, kwargs.get("fmt", PoseFormat()))
    assert "robot.csv" in str(info.value)


def test_pairs_and_list_errors(tmp_path, capsys):
    B, C = recording()
    fs_write(tmp_path / "l.yml", {"base2gripper": B, "target2cam": C})
    with pytest.raises(InputError, match="already names its direction"):
        read_handeye_pairs(tmp_path / "l.yml", PoseFormat(invert=True))
    fs_write(tmp_path / "two.yml", {"a": B, "b": C})
    with pytest.raises(InputError, match="expected T1_i/T2_i"):
        read_handeye_pairs(tmp_path / "two.yml")
    fs_write(tmp_path / "short.yml", {"base2gripper": B[:4], "target2cam": C})
    with pytest.raises(InputError, match="4 robot poses but 9"):
        read_handeye_pairs(tmp_path / "short.yml")
    matrix_rows(tmp_path / "r.csv", B)
    matrix_rows(tmp_path / "c.csv", C[:5])
    assert main(["handeye", "--robot-poses", str(tmp_path / "r.csv"), "--target-poses",
                 str(tmp_path / "c.csv")]) == 2
    assert "9 robot poses" in capsys.readouterr().err
    assert main(["handeye", "--robot-poses", str(tmp_path / "r.csv")]) == 2
    assert "--target-poses" in capsys.readouterr().err
    assert main(["handeye", str(tmp_path / "l.yml"), "--robot-format", "euler"]) == 2
    assert "euler-zyx" in capsys.readouterr().err
