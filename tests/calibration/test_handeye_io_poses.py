"""Hand-eye files (CSV, OpenCV FileStorage YAML), pose planning, the camodocal recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinecal import InputError
from kinecal.calibration.handeye import calibrate_handeye
from kinecal.calibration.handeye.poses import (
    flange_poses,
    random_poses,
    star_polygon_poses,
    star_step,
)
from kinecal.io.handeye import (
    FLANGE_COLUMNS,
    TARGET_COLUMNS,
    read_handeye_pairs,
    write_handeye_csv,
    write_handeye_yaml,
)
from kinecal.io.poses import canonical_poses
from kinecal.spatial import (
    invert_transform,
    matrix_from_axis_angle,
    rotation_angle,
    transform_from,
)

CAMODOCAL = (Path(__file__).resolve().parents[2] / "src" / "kinecal" / "datasets"
             / "handeye-camodocal" / "TransformPairsInput.yml")


def _poses(n=5, seed=0):
    rng = np.random.default_rng(seed)
    return transform_from(matrix_from_axis_angle(rng.normal(size=(n, 3))),
                          rng.normal(size=(n, 3)) * 100)


def test_csv_round_trip(tmp_path):
    F, C = _poses(6, 1), _poses(6, 2)
    write_handeye_csv(tmp_path / "p.csv", F, C)
    header = (tmp_path / "p.csv").read_text().splitlines()[0].split(",")
    assert header == FLANGE_COLUMNS + TARGET_COLUMNS
    F2, C2 = read_handeye_pairs(tmp_path / "p.csv")
    assert np.abs(F2 - F).max() < 1e-12 and np.abs(C2 - C).max() < 1e-12


def test_yaml_round_trip_and_opencv_reads_it(tmp_path):
    F, C = _poses(4, 3), _poses(4, 4)
    write_handeye_yaml(tmp_path / "p.yml", F, C)
    F2, C2 = read_handeye_pairs(tmp_path / "p.yml")
    # every reader rebuilds the poses from translation and unit quaternion (io.poses)
    assert np.array_equal(F2, canonical_poses(F)) and np.array_equal(C2, canonical_poses(C))
    assert np.abs(F2 - F).max() < 1e-13 and np.abs(C2 - C).max() < 1e-13
    cv2 = pytest.importorskip("cv2")
    fs = cv2.FileStorage(str(tmp_path / "p.yml"), cv2.FILE_STORAGE_READ)
    assert np.array_equal(fs.getNode("T2_3").mat(), C[3])
    assert fs.getNode("frameCount").real() == 4


def test_csv_errors_name_file_and_row(tmp_path):
    F, C = _poses(4, 5), _poses(4, 6)
    p = tmp_path / "p.csv"
    write_handeye_csv(p, F, C)
    lines = p.read_text().splitlines()
    cells = lines[3].split(",")
    cells[3] = "2.0"  # flange_qw of data row 3: not a unit quaternion
    lines[3] = ",".join(cells)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as exc:
        read_handeye_pairs(p)
    assert exc.value.row == 3 and "p.csv" in str(exc.value) and "unit quaternion" in str(exc.value)
    p.write_text("flange_x,flange_y\n1,2\n")
    with pytest.raises(InputError, match="missing column"):
        read_handeye_pairs(p)
    with pytest.raises(InputError, match="file type"):
        read_handeye_pairs(tmp_path / "p.txt")


def test_yaml_errors_name_station(tmp_path):
    F, C = _poses(4, 7), _poses(4, 8)
    C[2, :3, :3] *= 1.01
    write_handeye_yaml(tmp_path / "bad.yml", F, C)
    with pytest.raises(InputError) as exc:
        read_handeye_pairs(tmp_path / "bad.yml")
    # the FileStorage key names the station; no 0-based "row" in a 1-based contract
    assert exc.value.row is None and "T2_2" in str(exc.value) and "orthonormal" in str(exc.value)
    (tmp_path / "short.yml").write_text("%YAML:1.0\nframeCount: 1\n")
    with pytest.raises(InputError, match="at least 3"):
        read_handeye_pairs(tmp_path / "short.yml")
    (tmp_path / "broken.yml").write_text("%YAML:1.0\nframeCount: [\n")
    with pytest.raises(InputError, match="YAML"):
        read_handeye_pairs(tmp_path / "broken.yml")


def test_star_step():
    assert [star_step(n) for n in (3, 4, 5, 6, 7, 8, 19)] == [1, 1, 2, 1, 3, 3, 9]


@pytest.mark.parametrize("count", [5, 8, 19])
def test_star_scheme_geometry(count):
    d, r = 380.0, 60.0
    T = star_polygon_poses(d, r, count)
    p, z = T[:, :3, 3], T[:, :3, 2]
    assert np.allclose(p[:, 2], d) and np.allclose(np.linalg.norm(p[:, :2], axis=1), r)
    # every z axis points at the target centre
    assert np.allclose(z, -p / np.linalg.norm(p, axis=1, keepdims=True), atol=1e-12)
    # vertices visited in star order: angle step 2 pi k / N
    ang = np.arctan2(p[:, 1], p[:, 0])
    step = np.mod(np.diff(ang), 2 * np.pi)
    assert np.allclose(step, 2 * np.pi * star_step(count) / count)
    # first x axis tangent to the circle
    assert np.allclose(T[0, :3, 0], [0.0, 1.0, 0.0], atol=1e-12)
    # each step is a rotation about the horizontal axis perpendicular to the star edge
    rel = T[1:, :3, :3] @ np.swapaxes(T[:-1, :3, :3], 1, 2)
    from kinecal.spatial import axis_angle_from_matrix

    axes = axis_angle_from_matrix(rel)
    edge = p[1:] - p[:-1]
    assert np.allclose(axes[:, 2], 0.0, atol=1e-12)
    assert np.allclose(np.sum(axes * edge, axis=1), 0.0, atol=1e-9)


def test_pentagram_matches_paper_figure():
    """5 points: the pentagram {5/2}, vertices 144 deg apart in visiting order."""
    T = star_polygon_poses(380.0, 60.0, 5)
    ang = np.degrees(np.arctan2(T[:, 1, 3], T[:, 0, 3]))
    assert np.allclose(np.mod(ang, 360.0), [0.0, 144.0, 288.0, 72.0, 216.0])


def test_random_poses_and_flange_poses():
    T = random_poses(380.0, 60.0, 19, np.random.default_rng(0))
    p = T[:, :3, 3]
    assert np.all(np.linalg.norm(p[:, :2], axis=1) <= 60.0) and np.allclose(p[:, 2], 380.0)
    assert np.allclose(T[:, :3, 2], -p / np.linalg.norm(p, axis=1, keepdims=True))
    assert np.array_equal(T, random_poses(380.0, 60.0, 19, np.random.default_rng(0)))
    X = _poses(1, 9)[0]
    Y = _poses(1, 10)[0]
    F = flange_poses(T, X, Y)
    assert np.allclose(F @ X @ invert_transform(T), Y)
    with pytest.raises(InputError, match="radius"):
        star_polygon_poses(380.0, -1.0, 5)
    with pytest.raises(InputError, match="count"):
        random_poses(380.0, 60.0, 2)


def test_camodocal_conventions_and_outlier():
    """T1 = flange2base, T2 = target2cam, eye-to-hand: the reading with small residuals;
    station 36 is flagged by the robust refinement."""
    F, C = read_handeye_pairs(CAMODOCAL)
    assert F.shape == C.shape == (42, 4, 4)
    good = calibrate_handeye(F, C, setup="eye-to-hand", method="park", refine="none")
    wrong = calibrate_handeye(F, C, setup="eye-in-hand", method="park", refine="none")
    assert good.translation_rms < 0.01 and good.rotation_rms_deg < 5.0
    assert wrong.rotation_rms_deg > 5 * good.rotation_rms_deg
    swapped = calibrate_handeye(F, invert_transform(C), setup="eye-in-hand", method="park",
                                refine="none")
    assert swapped.translation_rms > 5 * good.translation_rms
    res = calibrate_handeye(F, C, setup="eye-to-hand", method="park", refine="lm")
    assert 36 in res.outliers and len(res.outliers) <= 4
    assert res.rotation_deg[36] > 10.0
    # the target pose (marker in the arm tip frame) agrees with the upstream tool's answer
    upstream_t = np.array([7.846e-03, 8.353e-02, -8.718e-03])
    assert np.linalg.norm(res.target[:3, 3] - upstream_t) < 0.03
    # (9.1 deg, 22 mm apart: a sanity check of the frames, a wrong reading is off by > 90 deg)
    assert np.degrees(rotation_angle(res.target[:3, :3].T @ _upstream_R())) < 15.0


def _upstream_R():
    return np.array([
        [-9.8070575963746975e-01, 1.8408167030060724e-01, 6.5803887979601350e-02],
        [4.9926199062053020e-02, -8.9600998786831365e-02, 9.9472560822752454e-01],
        [1.8900684554033920e-01, 9.7881847125794519e-01, 7.8681717464412104e-02],
    ])
