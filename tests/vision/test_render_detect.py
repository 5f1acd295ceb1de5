"""Rendered boards: corner accuracy, board orientation, rejection reasons."""

from __future__ import annotations

import re

import numpy as np
import pytest

from kinecal import InputError
from kinecal.calibration.handeye.camera import project
from kinecal.spatial import matrix_from_axis_angle, transform_from
from kinecal.vision.boards import Charuco, Chessboard, parse_board
from kinecal.vision.detect import QualityLimits, detect, orientation_ambiguous
from kinecal.vision.render import ImageConditions, plan_views, render_board

SPECS = ["chessboard:9x6:20", "charuco:7x5:30:22:DICT_5X5_100", "acircles:4x11:15"]


def _errors(board, K, dist, T, det):
    uv = project(K, dist, det.object_points(board) @ T[:3, :3].T + T[:3, 3])
    return np.linalg.norm(det.corners - uv, axis=1)


@pytest.mark.parametrize("spec,rms_max", [(SPECS[0], 0.04), (SPECS[1], 0.06), (SPECS[2], 0.12)])
def test_noise_free_corners_where_the_geometry_puts_them(camera, spec, rms_max):
    """The renderer and the detector agree: noise-free corners within a few hundredths of a
    pixel of the exact projection (measured: chessboard 0.020, ChArUco 0.034, circles
    0.077 px RMS; circle centres carry the known perspective bias)."""
    K, dist, size = camera
    board = parse_board(spec)
    errs = []
    for T in plan_views(board, K, dist, size, 4, rng=1):
        det = detect(render_board(board, K, dist, T, size, supersample=3), board)
        assert det.ok, det.reason
        errs.append(_errors(board, K, dist, T, det))
    e = np.concatenate(errs)
    assert np.sqrt(np.mean(e**2)) < rms_max and e.max() < 0.25


def test_chessboard_orientation_follows_the_board(camera):
    """Rolled by 180 deg (and 90 deg), the corner ids stay on the same physical corners."""
    K, dist, size = camera
    board = Chessboard(9, 6, 20.0)
    assert not orientation_ambiguous(board) and orientation_ambiguous(Chessboard(8, 6, 20.0))
    T0 = plan_views(board, K, dist, size, 1, rng=3, tilt_deg=10, roll_deg=0)[0]
    centre = board.object_points.mean(axis=0)
    for roll in (0.0, np.pi / 2, np.pi, -2.5):
        # turn the board about its own centre, seen from the same camera
        turn = transform_from(matrix_from_axis_angle([0, 0, roll]), centre) \
            @ transform_from(np.eye(3), -centre)
        T = T0 @ turn
        det = detect(render_board(board, K, dist, T, size), board)
        assert det.ok, det.reason
        assert _errors(board, K, dist, T, det).max() < 0.2, roll


def test_charuco_partial_view_accepted_when_enough_corners(camera):
    K, dist, size = camera
    board = parse_board(SPECS[1])
    assert isinstance(board, Charuco)
    T = plan_views(board, K, dist, size, 1, rng=2)[0].copy()
    T[0, 3] += T[2, 3] * 0.35 * size[0] / K[0, 0]  # a part of the board leaves the image
    det = detect(render_board(board, K, dist, T, size), board, QualityLimits(min_corners=8))
    assert det.ok and det.partial and 8 <= len(det.corners) < board.n_corners
    assert _errors(board, K, dist, T, det).max() < 0.3


@pytest.mark.parametrize("spec", SPECS)
def test_bad_images_rejected_with_reasons(camera, spec):
    K, dist, size = camera
    board = parse_board(spec)
    T = plan_views(board, K, dist, size, 1, rng=4)[0]
    half = T.copy()
    half[0, 3] += T[2, 3] * 0.45 * size[0] / K[0, 0]
    away = T.copy()
    away[0, 3] += T[2, 3] * 3.0
    none = detect(render_board(board, K, dist, away, size, ImageConditions(noise=2.0), rng=0),
                  board)
    assert not none.ok and none.reason.startswith("no board found")
    blur = detect(render_board(board, K, dist, T, size, ImageConditions(blur=5.0, noise=2.0),
                               rng=0), board)
    assert not blur.ok and "blurred" in blur.reason
    part = detect(render_board(board, K, dist, half, size), board)
    assert not part.ok
    if spec.startswith("chessboard"):
        assert part.reason.startswith("board partly visible")
    elif spec.startswith("charuco"):
        # says what was seen: markers found, corners interpolated, the threshold
        assert re.fullmatch(r"too few corners: (\d+) of 17 markers found, (\d+) of 24 corners "
                            r"interpolated; --min-corners 15 \(60 % of the board's, default\)",
                            part.reason), part.reason
        assert f"{len(part.corners)} of 24 corners" in part.reason
    else:
        assert part.reason.startswith("no board found") and "partly visible" in part.reason
    good = detect(render_board(board, K, dist, T, size, ImageConditions(blur=0.8, noise=3.0),
                               rng=0), board)
    assert good.ok and good.reason == "" and 0.5 < good.edge_width < 4.5


def test_border_and_back_side(camera):
    K, dist, size = camera
    board = Chessboard(9, 6, 20.0)
    T = plan_views(board, K, dist, size, 1, rng=5, margin_px=12)[0]
    det = detect(render_board(board, K, dist, T, size), board, QualityLimits(border=40.0))
    assert not det.ok and "from the image border" in det.reason
    back = T @ transform_from(matrix_from_axis_angle([np.pi, 0, 0]), [0, 0, 0])
    img = render_board(board, K, dist, back, size)
    assert not detect(img, board).ok


def test_board_specs():
    assert parse_board("chessboard:9x6:30").spec == "chessboard:9x6:30"
    b = parse_board("charuco:7x5:40:30:DICT_5X5_100")
    assert b.n_corners == 24 and b.spec == "charuco:7x5:40:30:DICT_5X5_100"
    assert parse_board("acircles:4x11:20").n_corners == 44
    pts = parse_board("chessboard:3x3:10").object_points
    assert np.allclose(pts[[0, 1, 3]], [[0, 0, 0], [10, 0, 0], [0, 10, 0]])
    for bad in ("chessboard:9x6", "chessboard:9*6:30", "chessboard:9x6:-3", "hexboard:3x3:1",
                "charuco:7x5:40:50:DICT_5X5_100", "charuco:7x5:40:30:DICT_NOPE",
                "charuco:20x20:40:30:DICT_4X4_50", "chessboard:1x6:30",
                "chessboard:3x2:10"):
        with pytest.raises(InputError, match="board"):
            parse_board(bad)


def test_truncated_jpeg_refused_after_a_pdf_report_in_the_same_process(tmp_path, monkeypatch):
    """WeasyPrint sets Pillow's LOAD_TRUNCATED_IMAGES for its whole process when imported
    (a PDF report): a truncated JPEG then loaded without error and its grey lower half
    reached the detector."""
    import cv2
    from PIL import ImageFile

    from kinecal.vision.image_files import check_image_file

    img = np.tile(np.arange(256, dtype=np.uint8), (240, 1))
    data = cv2.imencode(".jpg", img)[1].tobytes()
    path = tmp_path / "half.jpg"
    path.write_bytes(data[: len(data) // 2])
    monkeypatch.setattr(ImageFile, "LOAD_TRUNCATED_IMAGES", True)  # what the import does
    with pytest.raises(InputError, match="truncated or corrupt"):
        check_image_file(path)
    assert ImageFile.LOAD_TRUNCATED_IMAGES is True  # left as the process had it
