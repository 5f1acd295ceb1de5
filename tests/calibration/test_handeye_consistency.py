"""``handeye-inconsistent`` and the angle-unit checks of the pose readers: pose lists that
no X can join (inverted, quaternions x, y, z, w, degrees read as radians) are named, never
answered with a silent X or a unit warning that points elsewhere; clean data stay quiet."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal import diagnostics
from kinecal.calibration.handeye import calibrate_handeye
from kinecal.calibration.handeye.poses import random_poses
from kinecal.cli import main
from kinecal.cli._common import resolve_data_path
from kinecal.errors import InputError
from kinecal.experiments.li2024 import _measure
from kinecal.io.handeye import read_handeye_files, read_handeye_pairs
from kinecal.io.poses import PoseFormat
from kinecal.spatial import (
    invert_transform,
    matrix_from_quaternion,
    quaternion_from_matrix,
)


def _codes(F, C, **kw):
    with diagnostics.collect() as found:
        res = calibrate_handeye(F, C, **kw)
    return res, {d.code: d.message for d in found}


@pytest.fixture(scope="module")
def stations():
    rng = np.random.default_rng(11)
    return _measure(random_poses(380.0, 60.0, 15, rng), rng)


def test_clean_noisy_stations_give_no_warning(stations):
    _, found = _codes(*stations)
    assert found == {}


@pytest.mark.parametrize("name", ["handeye-camodocal", "handeye-tabb1"])
def test_real_recordings_give_no_inconsistency_warning(name):
    F, C = read_handeye_pairs(resolve_data_path(name + ":pairs"))
    setup = "eye-to-hand" if name == "handeye-camodocal" else "eye-in-hand"
    _, found = _codes(F, C, setup=setup)
    assert "handeye-inconsistent" not in found and "scale-mismatch" not in found


def test_inverted_robot_poses_are_named(stations):
    G, C = stations
    _, found = _codes(invert_transform(G), C)
    assert set(found) == {"handeye-inconsistent"}, found
    assert "--invert-robot" in found["handeye-inconsistent"]


def test_wrong_setup_is_named(stations):
    G, C = stations
    _, found = _codes(G, C, setup="eye-to-hand")
    assert "--setup eye-in-hand" in found["handeye-inconsistent"]


def test_quaternions_in_xyzw_order_are_named_not_a_unit_mismatch(stations):
    G, C = stations

    def xyzw(T):
        q = quaternion_from_matrix(T[:, :3, :3])
        out = T.copy()
        out[:, :3, :3] = matrix_from_quaternion(q[:, [1, 2, 3, 0]])  # (x, y, z, w) read as wxyz
        return out

    _, found = _codes(xyzw(G), xyzw(C))
    assert "scale-mismatch" not in found  # before: "looks like ... inches"
    assert "both quaternions read in (x, y, z, w) order" in found["handeye-inconsistent"]


def test_unit_mismatch_is_one_warning_not_two(stations):
    G, C = stations
    G = G.copy()
    G[:, :3, 3] /= 1000.0
    _, found = _codes(G, C)
    assert set(found) == {"scale-mismatch"}


def _euler_files(tmp_path, stations, unit):
    from scipy.spatial.transform import Rotation

    G, C = stations
    ang = Rotation.from_matrix(G[:, :3, :3]).as_euler("ZYX", degrees=unit == "deg")
    rob = tmp_path / "kuka.csv"
    np.savetxt(rob, np.c_[G[:, :3, 3], ang], delimiter=",", header="X,Y,Z,A,B,C",
               comments="", fmt="%.17g")
    q = quaternion_from_matrix(C[:, :3, :3])
    tgt = tmp_path / "board.csv"
    np.savetxt(tgt, np.c_[C[:, :3, 3], q], delimiter=",", header="x,y,z,qw,qx,qy,qz",
               comments="", fmt="%.17g")
    return rob, tgt


def test_degrees_read_as_radians_are_refused_with_the_row(tmp_path, stations):
    rob, tgt = _euler_files(tmp_path, stations, "deg")
    with pytest.raises(InputError, match=r"beyond 2 pi for radians.*euler-zyx:deg") as exc:
        read_handeye_files(rob, tgt, PoseFormat("euler-zyx"))
    assert exc.value.row == 1
    F, _ = read_handeye_files(rob, tgt, PoseFormat("euler-zyx", "deg"))
    assert np.allclose(F, stations[0], atol=1e-9)


def test_radians_read_as_degrees_warn_and_the_cli_names_it(tmp_path, stations, capsys):
    rob, tgt = _euler_files(tmp_path, stations, "rad")
    code = main(["handeye", "--robot-poses", str(rob), "--robot-format", "euler-zyx:deg",
                 "--target-poses", str(tgt), "--json"])
    err = capsys.readouterr().err
    assert code == 0
    assert "[angle-units]" in err and "[handeye-inconsistent]" in err  # before: no warning
    code = main(["handeye", "--robot-poses", str(rob), "--robot-format", "euler-zyx:deg",
                 "--target-poses", str(tgt), "--strict"])
    assert code == 2
