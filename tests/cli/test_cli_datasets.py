"""``kinecal datasets``: the bundled sets listed and written where a walkthrough needs them;
the synthetic handeye-formats files are what their generator writes and what they claim."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinecal.cli import main
from kinecal.datasets import DATASETS, dataset_dir, files


def handeye_formats() -> dict[str, np.ndarray]:
    """The generator of the bundled handeye-formats set: one eye-in-hand set-up, X with
    translation (25, -15, 70) mm, 9 stations of the star-polygon scheme; the robot poses as
    base2gripper 4x4 rows and KUKA X, Y, Z, A, B, C (deg), the board as tvec, rvec."""
    from kinecal.calibration.handeye.poses import flange_poses, star_polygon_poses
    from kinecal.spatial import invert_transform

    X = np.eye(4)
    X[:3, :3] = Rotation.from_rotvec([0.2, 0.1, 0.9]).as_matrix()
    X[:3, 3] = [25.0, -15.0, 70.0]
    Y = np.eye(4)
    Y[:3, :3] = Rotation.from_euler("xyz", [180.0, 0.0, 10.0], degrees=True).as_matrix()
    Y[:3, 3] = [650.0, 120.0, 40.0]
    cam2target = star_polygon_poses(400.0, 150.0, 9)
    G = flange_poses(cam2target, X, Y)
    C = invert_transform(cam2target)
    return {
        "base2gripper.csv": invert_transform(G).reshape(len(G), 16),
        "board.csv": np.c_[C[:, :3, 3], Rotation.from_matrix(C[:, :3, :3]).as_rotvec()],
        "kuka.csv": np.c_[G[:, :3, 3], Rotation.from_matrix(G[:, :3, :3]).as_euler(
            "ZYX", degrees=True)],
    }


def test_handeye_formats_are_their_generator():
    folder = dataset_dir("handeye-formats")
    for name, values in handeye_formats().items():
        skip = 0 if name == "base2gripper.csv" else 1  # the headerless matrix list
        shipped = np.loadtxt(folder / name, delimiter=",", skiprows=skip)
        np.testing.assert_allclose(shipped, values, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("args", [
    ["--robot-poses", "base2gripper.csv", "--invert-robot"],
    ["--robot-poses", "kuka.csv", "--robot-format", "euler-zyx:deg"],
])
def test_every_format_gives_the_same_x(args, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["datasets", "handeye-formats"]) == 0
    assert main(["handeye", *args, "--target-poses", "board.csv", "--target-format", "rotvec",
                 "--json"]) == 0
    X = np.asarray(json.loads(capsys.readouterr().out)["X"])
    np.testing.assert_allclose(X[:3, 3], [25.0, -15.0, 70.0], atol=1e-9)
    np.testing.assert_allclose(X[:3, :3], Rotation.from_rotvec([0.2, 0.1, 0.9]).as_matrix(),
                               atol=1e-12)


def test_list_and_write(tmp_path, capsys):
    assert main(["datasets", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)["datasets"]
    assert [d["name"] for d in listed] == list(DATASETS)
    out = tmp_path / "new" / "folder"
    assert main(["datasets", "kr16-urdf", "ur5-laser-tracker", "--out", str(out)]) == 0
    assert "kr16_2.urdf" in capsys.readouterr().err
    for name in ("kr16-urdf", "ur5-laser-tracker"):
        for src in files(name):
            dst = out / (f"{name}-LICENSE.txt" if src.name == "LICENSE" else src.name)
            assert dst.read_bytes() == src.read_bytes()
    assert main(["datasets", "kr16-urdf", "--out", str(out)]) == 0  # the same again: fine
    edited = out / "kr16_2.urdf"
    edited.write_text("mine")
    assert main(["datasets", "kr16-urdf", "--out", str(out)]) == 2
    assert "exists and differs" in capsys.readouterr().err
    assert edited.read_text() == "mine"  # never replaced
    assert main(["datasets", "nope"]) == 2
    assert "unknown set 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("device", ["/dev/full", "/dev/zero"])
def test_a_file_in_the_folder_linked_to_a_device_is_refused_without_reading_it(
        device, tmp_path, capsys):
    """``datasets ... --out d`` with ``d/grid.csv -> /dev/full`` read the device until a
    MemoryError; now it is a file that differs from the bundled one (exit 2), nothing
    written, and an identical copy is left as it is."""
    d = tmp_path / "d"
    d.mkdir()
    (d / "grid.csv").symlink_to(device)
    assert main(["datasets", "ur5-laser-tracker", "--out", str(d)]) == 2
    assert f"{d / 'grid.csv'} exists and differs from the bundled file" in \
        capsys.readouterr().err
    assert sorted(p.name for p in d.iterdir()) == ["grid.csv"]
    (d / "grid.csv").unlink()
    assert main(["datasets", "ur5-laser-tracker", "--out", str(d)]) == 0
    assert main(["datasets", "ur5-laser-tracker", "--out", str(d)]) == 0  # the same bytes


def test_a_loop_of_links_is_refused(tmp_path, capsys):
    """``datasets --out loop`` (``ln -s loop loop``) was an internal error."""
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    for out in (loop, loop / "sub"):
        assert main(["datasets", "ur5-laser-tracker", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"{out}: a loop of symbolic links" in err and err.count("\n") == 1
