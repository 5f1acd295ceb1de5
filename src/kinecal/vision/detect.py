"""Board detection with sub-pixel corners and per-image quality checks.

`detect` finds the board's corners in one grey image and either accepts it or rejects it
with a reason a user can act on, saying what was seen:

- ``no board found`` (nothing board-like; with the image's edge width when it is blurred;
  circle grids: how many dots were found);
- ``board partly visible`` (a chessboard cut by the image border or occluded: a part of
  the grid is found but not all of it; any corner closer to the border than the sub-pixel
  window);
- ``too few corners`` (ChArUco: ``13 of 17 markers found, 9 of 24 corners interpolated``,
  fewer than `QualityLimits.min_corners`);
- ``blurred`` (edge width above `QualityLimits.max_edge_width` pixels);
- ``too oblique`` is judged later from the board pose (`kinecal.vision.pnp`).

Chessboard corners come from ``cv2.findChessboardCorners`` refined by ``cv2.cornerSubPix``
on the image smoothed by a Gaussian of up to 1.5 px, with a window of 0.9 times the corner
spacing (half-width at most 15 px). On rendered images both choices lower the corner error
against OpenCV's customary 11 x 11 window on the raw image: noise-free 0.053 -> 0.021 px
RMS, with blur and noise 0.042 -> 0.036 px (tests/vision). ChArUco markers are found by
``cv2.aruco.CharucoDetector`` with its board-guided second search for the markers the
first pass missed (``tryRefineMarkers``: on industrial_calibration's real ``test_set_charuco``
the corners found in its five hardest images rise from 4-14 to 24 of 24); the corners are
refined again the same way as a chessboard's with the window kept inside the gap between
square corner and marker (noise-free 0.057 -> 0.040 px). OpenCV may list chessboard corners
starting from either end of the board; `detect` puts them in the board's own order by the
colour of the square diagonally outside corner 0 (black by the board's definition), so that
a board turned by 180 deg between images keeps its frame. Boards that look the same after a
turn (inner corner counts both even or both odd; symmetric circle grids) cannot be oriented
and are reported by `orientation_ambiguous`. Circle grids: `kinecal.vision.detect_circles`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.vision import require_cv2
from kinecal.vision.boards import Board, Charuco, Chessboard
from kinecal.vision.circle_grids import CircleGrid
from kinecal.vision.detect_chessboard import Survey, find_chessboard
from kinecal.vision.detect_circles import detect_circle_grid
from kinecal.vision.detection import Detection, QualityLimits, edge_width, orientation_ambiguous
from kinecal.vision.pixels import blurred_around, hull_polygon

Array = NDArray[np.float64]

__all__ = ["MIN_IMAGE_SIDE", "Detection", "QualityLimits", "Survey", "as_gray", "detect",
           "edge_width", "orientation_ambiguous"]


def _hull_mask(shape: tuple[int, int], pts: Array, grow: float) -> NDArray[np.bool_]:
    cv2 = require_cv2()
    mask = np.zeros(shape, np.uint8)
    cv2.fillConvexPoly(mask, hull_polygon(pts, grow), 1)
    return mask.astype(bool)


def _board_edge_width(gray: NDArray[np.uint8], pts: Array, grow: float) -> float:
    """`edge_width` within the grown hull of `pts`, on the hull's bounding box plus 2 px
    (the Sobel gradient needs one; same pixels, same values as on the whole image)."""
    cv2 = require_cv2()
    poly = hull_polygon(pts, grow)
    h, w = gray.shape
    x0, y0 = np.maximum(poly.min(axis=0) - 2, 0)
    x1, y1 = np.minimum(poly.max(axis=0) + 3, (w, h))
    if x1 <= x0 or y1 <= y0:
        return float("nan")
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.fillConvexPoly(mask, poly - np.array([x0, y0], np.int32), 1)
    return edge_width(gray[y0:y1, x0:x1], mask.view(bool))


def _spacing(corners: Array, cols: int) -> float:
    """Smallest neighbour distance along rows and columns of a full grid (px)."""
    g = corners.reshape(-1, cols, 2)
    d = [np.linalg.norm(np.diff(g, axis=1), axis=2).min() if cols > 1 else np.inf,
         np.linalg.norm(np.diff(g, axis=0), axis=2).min() if g.shape[0] > 1 else np.inf]
    return float(min(d))


#: cornerSubPix stops when a corner moves less than 1e-3 px, or after 30 iterations
#: (OpenCV's tutorial criteria): a tighter 1e-5 px took 100 iterations per corner (it is
#: never reached: the iteration's own noise is larger) for the same corners (bench: RMS
#: 0.0327 vs 0.0320 px against the exact projections) at 2.3 times the detection's time
_SUBPIX_STOP = (3, 30, 1e-3)  # cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT


def _subpix(gray: NDArray[np.uint8], corners: Array, spacing: float) -> Array:
    """``cv2.cornerSubPix`` on the image smoothed by a Gaussian of sigma ``min(1.5,
    spacing / 12)`` px, window half-width ``0.45 spacing`` (2 to 15 px)."""
    cv2 = require_cv2()
    half = int(np.clip(np.floor(0.45 * spacing), 2, 15))
    sigma = min(1.5, spacing / 12.0)
    img = blurred_around(gray, corners, sigma, 2 * half + 3) if sigma >= 0.3 else gray
    crit = _SUBPIX_STOP
    c = corners.astype(np.float32).reshape(-1, 1, 2)
    return cv2.cornerSubPix(img, c, (half, half), (-1, -1), crit).reshape(-1, 2).astype(float)


def _sample(gray: NDArray[np.uint8], p: Array) -> float:
    cv2 = require_cv2()
    patch = cv2.getRectSubPix(gray, (3, 3), (float(p[0]), float(p[1])))
    return float(patch.mean())


def _orient_chessboard(gray: NDArray[np.uint8], corners: Array, board: Chessboard) -> Array:
    """Corners in the board's order: right-handed, black square outside corner 0."""
    cols, rows = board.cols, board.rows
    g = corners.reshape(rows, cols, 2)
    # handedness: the board's x and y axes must appear counter-clockwise-free as in a front
    # view (image x right, y down): cross((c1 - c0), (c_cols - c0)) > 0
    ex, ey = g[0, 1] - g[0, 0], g[1, 0] - g[0, 0]
    if ex[0] * ey[1] - ex[1] * ey[0] < 0:
        g = g[:, ::-1]
    if board.symmetric:
        return g.reshape(-1, 2)
    ex, ey = g[0, 1] - g[0, 0], g[1, 0] - g[0, 0]
    outside = _sample(gray, g[0, 0] - 0.5 * ex - 0.5 * ey)  # square (0, 0): black
    beside = _sample(gray, g[0, 0] + 0.5 * ex - 0.5 * ey)  # square (1, 0): white
    if outside > beside:  # listed from the other end: half turn
        g = g[::-1, ::-1]
    return g.reshape(-1, 2)


def _detect_chessboard(gray: NDArray[np.uint8], board: Chessboard, det: Detection,
                       limits: QualityLimits, session: Survey | None = None) -> Detection:
    corners, seen = find_chessboard(gray, (board.cols, board.rows), session)
    if corners is None:
        return det.reject(_why_no_chessboard(gray, board, limits, seen))
    c = _subpix(gray, corners, _spacing(corners, board.cols))
    det.corners = _orient_chessboard(gray, c, board)
    det.ids = np.arange(board.n_corners)
    return det


def _why_no_chessboard(gray: NDArray[np.uint8], board: Chessboard, limits: QualityLimits,
                       seen: tuple[int, int] | bool) -> str:
    """Reason for a failed chessboard detection: a whole grid of another size (`seen`),
    blur, a part of a grid seen (`seen` True), nothing."""
    if not isinstance(seen, bool):
        return (f"board size differs: a whole chessboard of {seen[0]}x{seen[1]} inner "
                f"corners is seen, not the {board.cols}x{board.rows} of the board spec "
                "(count the inner corners, where four squares meet)")
    w = edge_width(gray)
    if np.isfinite(w) and w > limits.max_edge_width:
        return f"no board found; the image is blurred (edge width {w:.1f} px)"
    if seen:
        return (f"board partly visible: a chessboard grid is seen but not all {board.cols}x"
                f"{board.rows} inner corners (cut by the image border or occluded)")
    return f"no board found (no {board.cols}x{board.rows} chessboard corner grid)"


def _detect_charuco(gray: NDArray[np.uint8], board: Charuco, det: Detection,
                    limits: QualityLimits) -> Detection:
    cv2 = require_cv2()
    params = cv2.aruco.CharucoParameters()
    params.tryRefineMarkers = True  # look again for the markers the layout predicts
    detector = cv2.aruco.CharucoDetector(board.cv_board(), params,
                                         cv2.aruco.DetectorParameters())
    corners, ids, _, marker_ids = detector.detectBoard(gray)
    n = 0 if ids is None else len(ids)
    # the markers of this board (another board's in the same image have other ids)
    own = board.marker_ids
    nm = 0 if marker_ids is None else sum(int(m) in own for m in np.ravel(marker_ids))
    need = limits.corners_needed(board)
    det.seen = (f"{nm} of {board.cols * board.rows // 2} markers found, {n} of "
                f"{board.n_corners} corners interpolated")
    if n == 0:
        w = edge_width(gray)
        if nm:
            return det.reject(f"board partly visible: {det.seen}")
        if np.isfinite(w) and w > limits.max_edge_width:
            return det.reject(f"no board found; the image is blurred (edge width {w:.1f} px)")
        return det.reject(f"no board found (no {board.dictionary} markers detected)")
    c = corners.reshape(-1, 2).astype(float)
    i = ids.ravel().astype(np.intp)
    order = np.argsort(i)
    c, i = c[order], i[order]
    if len(c) >= 2:
        c = _refine_charuco(gray, c, board)
    det.corners, det.ids = c, i
    det.partial = n < board.n_corners
    if n < need:
        default = "" if limits.min_corners is not None else " (60 % of the board's, default)"
        return det.reject(f"too few corners: {det.seen}; --min-corners {need}{default}")
    if n >= 3 and _collinear(board.object_points[i]):
        return det.reject(f"corners on one line: {det.seen}, all on one row or column of "
                          "the board (no board pose)")
    return det


def _refine_charuco(gray: NDArray[np.uint8], c: Array, board: Charuco) -> Array:
    """Re-refine ChArUco corners on the smoothed image, window inside the marker-free gap."""
    cv2 = require_cv2()
    d = np.linalg.norm(c[:, None] - c[None, :], axis=2)
    np.fill_diagonal(d, np.inf)
    spacing = float(np.median(d.min(axis=1)))
    gap = spacing * (board.square - board.marker) / (2.0 * board.square)
    half = int(np.clip(round(gap), 2, 15))
    sigma = 1.0 if half >= 3 else 0.7
    crit = _SUBPIX_STOP
    smooth = blurred_around(gray, c, sigma, 2 * half + 3)  # the blur only where read
    return cv2.cornerSubPix(smooth, c.astype(np.float32).reshape(-1, 1, 2), (half, half),
                            (-1, -1), crit).reshape(-1, 2).astype(float)


def _collinear(P: Array) -> bool:
    """Board points ``(N, 3)`` on one line (second singular value ~ 0)."""
    s = np.linalg.svd(P[:, :2] - P[:, :2].mean(axis=0), compute_uv=False)
    return bool(s[1] <= 1e-9 * max(s[0], 1e-300))


#: shortest image side a board is looked for in (px): OpenCV's chessboard detector fails
#: below 10 px, and no board's corners can be told apart in fewer than 3 px per square
MIN_IMAGE_SIDE = 32


def as_gray(image: Any) -> NDArray[np.uint8]:
    """An image array as 8-bit grey.

    Parameters
    ----------
    image : ndarray, shape (h, w), (h, w, 1), (h, w, 3) or (h, w, 4)
        Grey, BGR or BGRA; ``uint8``, ``uint16`` (scaled by 1/256 as OpenCV reads 16-bit
        files), ``bool`` (0 / 255) or float in 0..255 (clipped).

    Raises
    ------
    TypeError
        Not an array of numbers.
    InputError
        Another shape, or a float image with NaN or infinity.
    """
    cv2 = require_cv2()
    gray = np.asarray(image)
    if gray.dtype == bool:
        gray = gray.astype(np.uint8) * 255
    if not (np.issubdtype(gray.dtype, np.integer) or np.issubdtype(gray.dtype, np.floating)):
        raise TypeError(f"image: expected an array of numbers, got dtype {gray.dtype}")
    if gray.ndim == 3 and gray.shape[2] == 1:
        gray = gray[:, :, 0]
    if gray.ndim != 2 and not (gray.ndim == 3 and gray.shape[2] in (3, 4)):
        raise InputError(f"image of shape {gray.shape}: expected (h, w) grey, (h, w, 3) BGR "
                         "or (h, w, 4) BGRA")
    if np.issubdtype(gray.dtype, np.floating) and not np.isfinite(gray).all():
        raise InputError("image: NaN or infinite pixel values")
    if gray.dtype == np.uint16:
        gray = (gray >> 8).astype(np.uint8)
    elif gray.dtype != np.uint8:
        gray = np.clip(gray, 0, 255).astype(np.uint8)
    if gray.ndim == 3 and gray.size:
        code = cv2.COLOR_BGR2GRAY if gray.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        gray = cv2.cvtColor(np.ascontiguousarray(gray), code)
    return gray


def detect(image: NDArray[Any], board: Board, limits: QualityLimits | None = None,
           session: Survey | None = None) -> Detection:
    """Detect `board` in `image` and run the image-level quality checks.

    Parameters
    ----------
    image : ndarray, shape (h, w) or (h, w, 3)
        8-bit grey or BGR image (colour is converted to grey; see `as_gray`).
    board : Board
    limits : QualityLimits, optional
    session : Survey, optional
        Shared by the images of one recording (`kinecal.vision.detect_chessboard.Survey`).

    Returns
    -------
    Detection
        ``ok`` False with a ``reason`` when rejected (also an image with a side shorter
        than `MIN_IMAGE_SIDE`).
    """
    limits = limits or QualityLimits()
    gray = as_gray(image)
    h, w = gray.shape
    det = Detection(True, "", size=(w, h))
    if min(h, w) < MIN_IMAGE_SIDE:
        return det.reject(f"image of {w}x{h} px: too small to show a board (a side shorter "
                          f"than {MIN_IMAGE_SIDE} px)")
    if isinstance(board, Chessboard):
        det = _detect_chessboard(gray, board, det, limits, session)
    elif isinstance(board, Charuco):
        det = _detect_charuco(gray, board, det, limits)
    elif isinstance(board, CircleGrid):
        det = detect_circle_grid(gray, board, det, limits)
    else:  # pragma: no cover - parse_board only makes these kinds
        raise TypeError(f"unsupported board {board!r}")
    if not det.ok or len(det.corners) == 0:
        return det
    c = det.corners
    near = np.minimum.reduce([c[:, 0], c[:, 1], w - 1 - c[:, 0], h - 1 - c[:, 1]])
    if near.min() < limits.border:
        return det.reject(f"board partly visible: a corner {max(near.min(), 0):.1f} px from "
                          f"the image border (< {limits.border:g} px)")
    if len(c) >= 3:
        det.edge_width = _board_edge_width(gray, c, 1.15)
        if np.isfinite(det.edge_width) and det.edge_width > limits.max_edge_width:
            return det.reject(f"blurred: edge width {det.edge_width:.1f} px > "
                              f"{limits.max_edge_width:g} px")
    return det
