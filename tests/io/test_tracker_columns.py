"""Tracker files' optional column sets: named Euler conventions against scipy, stations,
per-axis standard deviations, and the bad inputs each refuses."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kinecal
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.measurements import read_measurements, write_measurements
from kinecal.io.orientation import EULER_FORMATS, euler_matrix, euler_rates, rotation_sigma
from kinecal.io.poses import PoseFormat, read_poses


def _scipy_name(seq: str, intrinsic: bool) -> str:
    return seq.upper() if intrinsic else seq


@pytest.mark.parametrize("name", sorted(EULER_FORMATS))
def test_euler_conventions_match_scipy(name):
    seq, intrinsic = EULER_FORMATS[name]
    rng = np.random.default_rng(len(name) + sum(map(ord, name)))
    angles = rng.uniform(-np.pi, np.pi, (20, 3))
    angles[:, 1] = rng.uniform(0.1, np.pi - 0.1, 20) if seq[0] == seq[2] else \
        rng.uniform(-1.5, 1.5, 20)
    expect = Rotation.from_euler(_scipy_name(seq, intrinsic), angles).as_matrix()
    np.testing.assert_allclose(euler_matrix(angles, seq, intrinsic), expect, atol=1e-14)
    # and back: scipy's angles of our matrices rebuild them
    again = Rotation.from_matrix(euler_matrix(angles, seq, intrinsic)).as_euler(
        _scipy_name(seq, intrinsic))
    np.testing.assert_allclose(euler_matrix(again, seq, intrinsic), expect, atol=1e-12)


@pytest.mark.parametrize("name", ["intrinsic-xyz", "extrinsic-zyx", "intrinsic-zxz"])
def test_euler_rates_are_the_derivative(name):
    seq, intrinsic = EULER_FORMATS[name]
    a = np.array([0.3, 0.7, -1.1])
    E = euler_rates(a, seq, intrinsic)
    h = 1e-7
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        dR = euler_matrix(a + d, seq, intrinsic) @ euler_matrix(a - d, seq, intrinsic).T
        w = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / 2
        np.testing.assert_allclose(E[:, k], w / (2 * h), atol=1e-7)


def _ur5_rows(tmp_path, extra: dict, n: int = 6):
    model = kinecal.load_model("ur5")
    sim = kinecal.simulate(model, n, rng=1, orientation=True)
    q = np.degrees(sim.data.q)
    cols = {f"q{i + 1}": q[:, i] for i in range(6)}
    cols.update({c: sim.data.xyz[:, k] for k, c in enumerate("xyz")})
    cols.update(extra)
    path = tmp_path / "rows.csv"
    lines = [",".join(cols)]
    for r in range(n):
        lines.append(",".join(str(v[r]) for v in cols.values()))
    path.write_text("\n".join(lines) + "\n")
    return model, sim, path


def test_tmac_euler_columns_read_as_scipy_intrinsic_xyz(tmp_path):
    rng = np.random.default_rng(4)
    ang = rng.uniform(-170, 170, (6, 3))
    ang[:, 1] = rng.uniform(-85, 85, 6)
    sig = rng.uniform(0.001, 0.01, (6, 6))
    extra = {"a": ang[:, 0], "b": ang[:, 1], "c": ang[:, 2],
             **{c: sig[:, k] for k, c in enumerate(("sx", "sy", "sz", "srx", "sry", "srz"))}}
    model, _, path = _ur5_rows(tmp_path, extra)
    data = read_measurements(path, model, "intrinsic-xyz:deg")
    expect = Rotation.from_euler("XYZ", ang, degrees=True).as_matrix()
    np.testing.assert_allclose(data.rotations, expect, atol=1e-12)
    np.testing.assert_allclose(data.sigma[:, :3], sig[:, :3])
    # the angle deviations about the measurement frame's axes: first-order propagation
    E = euler_rates(np.radians(ang), "xyz", True)
    var = np.einsum("nij,nj,nij->ni", E, np.radians(sig[:, 3:]) ** 2, E)
    np.testing.assert_allclose(data.sigma[:, 3:], np.sqrt(var), rtol=1e-12)
    # the same format reads a pose file (handeye --robot-format)
    poses = read_poses(path, PoseFormat.parse("intrinsic-xyz:deg"))
    np.testing.assert_allclose(poses[:, :3, :3], expect, atol=1e-12)
    # written back as quaternions with deviations about the axes: the same rows
    write_measurements(tmp_path / "back.csv", data, model)
    back = read_measurements(tmp_path / "back.csv", model)
    np.testing.assert_allclose(back.rotations, data.rotations, atol=1e-12)
    np.testing.assert_allclose(back.sigma, data.sigma, rtol=1e-12)
    np.testing.assert_allclose(rotation_sigma("quaternion", None, back.sigma[:, 3:]),
                               back.sigma[:, 3:])


def test_station_column_names_the_setups(tmp_path):
    model, _, path = _ur5_rows(tmp_path, {"station": np.array(["B", "A", "B", "B", "A", "C"])})
    data = read_measurements(path, model)
    assert data.station_names == ("B", "A", "C")
    assert data.station.tolist() == [0, 1, 0, 0, 1, 2]
    assert len(data.subset(np.array([1, 4]))) == 2


@pytest.mark.parametrize(("extra", "match"), [
    ({"station": np.array(["A", "A", "", "B", "B", "B"])}, "station"),
    ({"station": np.array(["A", "A.1", "A", "B", "B", "B"])}, "without dots"),
    ({"station": np.array(["A", "a@b", "A", "B", "B", "B"])}, "without dots"),
    ({"qw": np.ones(6), "qx": np.zeros(6), "qy": np.zeros(6)}, "qw, qx, qy, qz"),
    ({"qw": np.full(6, 0.9), "qx": np.zeros(6), "qy": np.zeros(6), "qz": np.zeros(6)},
     "unit quaternion"),
    ({"sx": np.full(6, 0.01), "sy": np.full(6, -0.01), "sz": np.full(6, 0.01)},
     "positive standard deviation"),
    ({"sx": np.full(6, 0.01), "sy": np.full(6, 0.01)}, "sx, sy, sz"),
    ({"sx": np.ones(6), "sy": np.ones(6), "sz": np.ones(6), "srx": np.ones(6),
      "sry": np.ones(6), "srz": np.ones(6)}, "without a measured orientation"),
    ({"roll": np.zeros(6), "pitch": np.zeros(6), "yaw": np.zeros(6)}, "orientation-format"),
])
def test_bad_tracker_columns_are_refused(tmp_path, extra, match):
    model, _, path = _ur5_rows(tmp_path, extra)
    with pytest.raises(InputError, match=match):
        read_measurements(path, model)


def test_orientation_format_errors_name_the_columns(tmp_path):
    model, _, path = _ur5_rows(tmp_path, {"a": np.zeros(6), "b": np.zeros(6)})
    with pytest.raises(InputError, match=r"missing column.*c"):
        read_measurements(path, model, "intrinsic-xyz:deg")
    with pytest.raises(InputError, match="intrinsic-SEQ"):
        read_measurements(path, model, "intrinsic-xyq")


def test_command_line_refuses_bad_options_in_one_line(tmp_path, capsys):
    _, _, path = _ur5_rows(tmp_path, {})
    for args, match in [
        (["--orientation-format", "euler-abc"], "--orientation-format"),
        (["--validate-register", "all"], "--validate-register: applies with --validate"),
        (["--validate", str(path), "--validate-register", "150%"], "0 < N < 100"),
    ]:
        assert main(["calibrate", "ur5", str(path), *args]) == 2
        err = capsys.readouterr().err
        assert match in err and "Traceback" not in err
