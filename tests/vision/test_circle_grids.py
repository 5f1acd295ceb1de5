"""Symmetric circle grids and industrial_calibration's modified circle grid: definition,
rendering and detection, orientation, rejection reasons, a hand-eye scene."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal import InputError
from kinecal.calibration.handeye.camera import project
from kinecal.calibration.handeye.errors import pose_error
from kinecal.spatial import matrix_from_axis_angle, transform_from
from kinecal.vision.boards import ModifiedCircleGrid, SymmetricCircleGrid, parse_board
from kinecal.vision.detect import detect, orientation_ambiguous
from kinecal.vision.intrinsics import CameraIntrinsics
from kinecal.vision.pipeline import calibrate_handeye_images
from kinecal.vision.render import ImageConditions, plan_views, render_board, render_handeye_scene

pytest.importorskip("cv2")


def _errors(board, K, dist, T, corners):
    uv = project(K, dist, board.object_points @ T[:3, :3].T + T[:3, 3])
    return np.linalg.norm(corners - uv, axis=1)


def _up_to_symmetry(board, K, dist, T, det):
    """Centre errors under the labelling of the board's symmetries that fits best."""
    options = [det.corners]
    for _, perm in board.symmetries():
        alt = np.empty_like(det.corners)
        alt[perm] = det.corners
        options.append(alt)
    return min((_errors(board, K, dist, T, c) for c in options), key=lambda e: e.max())


def test_industrial_calibration_definition():
    """modcircles ids and coordinates as industrial_calibration's ModifiedCircleGridTarget:
    ids like text from the top left, origin (the large dot) at the bottom left, x right,
    y up the page, z out of it (seen from +z)."""
    b = parse_board("modcircles:10x10:25.4")
    assert isinstance(b, ModifiedCircleGrid) and b.n_corners == 100 and b.faces == -1.0
    P = b.object_points
    top = 9 * 25.4
    assert np.allclose(P[[0, 9, 90, 99]], [[0, top, 0], [top, top, 0], [0, 0, 0], [top, 0, 0]])
    assert b.origin_id == 90 and np.allclose(P[b.origin_id], 0.0)
    d = b.dot_diameters()
    assert d[90] == pytest.approx(2 * d[0]) and d[0] == pytest.approx(0.4 * 25.4)
    assert not orientation_ambiguous(b) and b.spec == "modcircles:10x10:25.4"
    c = parse_board("circles:7x6:20:9")
    assert isinstance(c, SymmetricCircleGrid) and c.spec == "circles:7x6:20:9"
    assert np.allclose(c.object_points[[0, 1, 7]], [[0, 0, 0], [20, 0, 0], [0, 20, 0]])
    assert orientation_ambiguous(c) and len(c.symmetries()) == 1
    assert len(parse_board("circles:5x5:20").symmetries()) == 3  # quarter turns too
    for bad in ("circles:7x6", "circles:7x6:20:20", "circles:2x6:20", "modcircles:5x5:10:7",
                "modcircles:5x5:10:-1", "circles:7x6:20:9:1"):
        with pytest.raises(InputError, match="board"):
            parse_board(bad)


@pytest.mark.parametrize("spec,rms_max", [("circles:7x6:15", 0.06), ("circles:5x5:18", 0.08),
                                          ("modcircles:7x5:15", 0.08),
                                          ("modcircles:10x10:10", 0.05)])
def test_noise_free_centres_where_the_geometry_puts_them(camera, spec, rms_max):
    """Rendered dots found at the projections of their centres (measured: 0.032, 0.044,
    0.042 and 0.023 px RMS; the rest is the centroid's perspective bias), symmetric grids
    up to their symmetry, modified grids exactly in their own ids."""
    K, dist, size = camera
    board = parse_board(spec)
    errs = []
    for T in plan_views(board, K, dist, size, 3, rng=1):
        det = detect(render_board(board, K, dist, T, size), board)
        assert det.ok, det.reason
        errs.append(_up_to_symmetry(board, K, dist, T, det) if board.symmetries()
                    else _errors(board, K, dist, T, det.corners))
    e = np.concatenate(errs)
    assert np.sqrt(np.mean(e**2)) < rms_max and e.max() < 0.25


@pytest.mark.parametrize("spec", ["modcircles:6x6:15", "modcircles:7x5:15"])
def test_origin_dot_fixes_the_frame_at_any_roll(camera, spec):
    """Turned by quarter turns in its plane (square grid; half turns otherwise), the ids
    stay on the same dots; symmetric grids of the same size cannot do that."""
    K, dist, size = camera
    board = parse_board(spec)
    T0 = plan_views(board, K, dist, size, 1, rng=3, tilt_deg=15, roll_deg=0)[0]
    centre = board.object_points.mean(axis=0)
    rolls = (0.0, np.pi / 2, np.pi, -np.pi / 2) if board.cols == board.rows else (0.0, np.pi)
    for roll in rolls:
        turn = transform_from(matrix_from_axis_angle([0, 0, roll]), centre) \
            @ transform_from(np.eye(3), -centre)
        T = T0 @ turn
        det = detect(render_board(board, K, dist, T, size), board)
        assert det.ok, det.reason
        assert _errors(board, K, dist, T, det.corners).max() < 0.25, roll


def test_rejections_say_what_was_seen(camera):
    K, dist, size = camera
    board = parse_board("circles:7x6:15")
    T = plan_views(board, K, dist, size, 1, rng=4)[0]
    half = T.copy()
    half[0, 3] += T[2, 3] * 0.45 * size[0] / K[0, 0]
    part = detect(render_board(board, K, dist, half, size), board)
    n = int(part.seen.split()[0])
    assert not part.ok and 0 < n < 42
    assert part.reason == (f"no board found: {n} dots detected, the 7x6 circle grid has 42 "
                           "(partly visible, or dots too small or blurred; circle grids are "
                           "found whole)")
    # a plain symmetric grid is not a modified one: no corner dot stands out
    img = render_board(parse_board("circles:7x5:15"), K, dist, T, size)
    mod = detect(img, parse_board("modcircles:7x5:15"))
    assert not mod.ok and mod.reason.startswith("origin dot not found: the corner dots are")
    blur = detect(render_board(board, K, dist, T, size, ImageConditions(blur=5.0, noise=2.0),
                               rng=0), board)
    assert not blur.ok and "blurred" in blur.reason


def test_square_symmetric_grid_frames_turned_back_in_a_hand_eye_scene(camera):
    """circles:5x5 looks the same after any quarter turn: views rolled anywhere in +-180
    deg are listed in several frames; the robot poses put them back (board-turned) and X
    comes out as from an asymmetric board."""
    K, dist, size = camera
    board = parse_board("circles:5x5:20")
    scene = render_handeye_scene(board, K, dist, size, 8, seed=5, supersample=2,
                                 conditions=ImageConditions(noise=1.5, blur=0.6),
                                 view_options={"roll_deg": 180.0})
    res = calibrate_handeye_images(scene.images, scene.flange2base, board,
                                   intrinsics=CameraIntrinsics(K, dist, size))
    codes = [w["code"] for w in res.warnings]
    assert codes[:2] == ["board-symmetric", "board-turned"], codes
    assert "90 deg and 180 deg and 270 deg" in res.warnings[0]["message"]
    rot, tr = pose_error(res.X, scene.X)
    assert rot < 0.05 and tr < 0.3 and res.outliers == []
