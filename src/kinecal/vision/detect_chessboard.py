"""Finding a chessboard's inner corners: fast on large images, quick to say what is wrong.

`find_chessboard` returns the corners of a chessboard of the spec's size (pixel accuracy;
`kinecal.vision.detect` refines them to sub-pixels on the full image) or the reason there
are none:

1. ``cv2.findChessboardCorners`` on the image reduced by an integer factor (area
   averaging) when its short side is at least `DOWNSCALE_SIDE` pixels: the detector's cost
   grows with the pixels, and the corners it returns only seed the sub-pixel search on the
   full image (their error stays within its window). On failure the full image follows.
2. When the spec's grid is not found (on the full image too, unless earlier images of the
   same session (`Survey`) already showed a grid of another size), the grid that *is* seen
   is surveyed on the reduced image (``cv2.findChessboardCornersSB`` with
   ``CALIB_CB_LARGER``, the grid's outer
   rows and columns that are no corner where four squares meet trimmed by the saddle test
   of `_saddle_scores`: the sector detector adds the row between the outermost squares
   and the white margin). A whole grid of another size is named at once ("a whole
   chessboard of 9x6 inner corners is seen, not the 6x10 of the board spec") without the
   full-image searches, which for a wrong size cost a second per image and find nothing.
3. Otherwise the full image, then the sector-based detector (blur, strong distortion).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal.vision import require_cv2

Array = NDArray[np.float64]

__all__ = ["DOWNSCALE_SIDE", "Survey", "find_chessboard", "seen_grid"]

#: images whose short side is at least this (px) are searched reduced by an integer factor
#: first, to a short side of at least half of it
DOWNSCALE_SIDE = 480
#: a grid point is a corner where four squares meet when its saddle score exceeds this
#: (1: two dark and two bright quadrants, opposite alike; 0.5: a square beside the margin)
SADDLE = 0.75


def _factor(shape: tuple[int, ...]) -> int:
    return max(1, int(min(shape[:2]) // (DOWNSCALE_SIDE // 2)) // 2 * 2) \
        if min(shape[:2]) >= DOWNSCALE_SIDE else 1


def _reduced(gray: NDArray[np.uint8], f: int) -> NDArray[np.uint8]:
    cv2 = require_cv2()
    if f == 1:
        return gray
    h, w = gray.shape
    return cv2.resize(gray[: h - h % f, : w - w % f], (w // f, h // f),
                      interpolation=cv2.INTER_AREA)


class Survey:
    """What one detection session's images showed: after two whole grids of another size
    than the spec's (a wrong ``--board``), the other images are surveyed before the
    full-image search, which for a wrong size costs a second each (threads may race on the
    count: only the order of the searches depends on it, not their outcome)."""

    def __init__(self) -> None:
        self.other_size = 0

    @property
    def first(self) -> bool:
        return self.other_size >= 2


def find_chessboard(gray: NDArray[np.uint8], size: tuple[int, int],
                    session: Survey | None = None
                    ) -> tuple[Array | None, tuple[int, int] | bool]:
    """The inner corners ``(cols * rows, 2)`` of a chessboard of `size` ``(cols, rows)`` in
    OpenCV's listing (full-image pixels), or None and what the survey saw instead: the
    ``(cols, rows)`` of a whole grid of another size, True for a part of a grid (cut by the
    border, occluded), False for none; see the module docstring."""
    cv2 = require_cv2()
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH + cv2.CALIB_CB_NORMALIZE_IMAGE
    f = _factor(gray.shape)
    small = _reduced(gray, f)
    found, corners = cv2.findChessboardCorners(small, size, flags=flags)
    if found:
        return (corners.reshape(-1, 2).astype(float) + 0.5) * f - 0.5, False
    survey_first = session is not None and session.first
    if f > 1 and not survey_first:  # a board too small for the reduced image: the full one
        found, corners = cv2.findChessboardCorners(gray, size, flags=flags)
        if found:
            return corners.reshape(-1, 2).astype(float), False
    seen = seen_grid(small)
    if seen is True and f > 1:  # a part on the reduced image: the full one may show it whole
        seen = seen_grid(gray)
    if not isinstance(seen, bool) and sorted(seen) != sorted(size):
        if session is not None:
            session.other_size += 1
        return None, _as_spec(seen, size)
    if f > 1 and survey_first:
        found, corners = cv2.findChessboardCorners(gray, size, flags=flags)
        if found:
            return corners.reshape(-1, 2).astype(float), False
    try:  # the sector-based detector copes better with blur and strong distortion
        found, corners = cv2.findChessboardCornersSB(gray, size, 0)
    except cv2.error:
        found = False
    if found:
        return corners.reshape(-1, 2).astype(float), False
    return None, not isinstance(seen, bool) or seen


def _as_spec(seen: tuple[int, int], size: tuple[int, int]) -> tuple[int, int]:
    """`seen` in the order of the spec (the larger count first when the spec's is)."""
    big, small = max(seen), min(seen)
    return (big, small) if size[0] >= size[1] else (small, big)


def seen_grid(gray: NDArray[np.uint8]) -> tuple[int, int] | bool:
    """Columns and rows of the whole chessboard grid the image shows (its inner corners);
    True when a part of a grid is seen (cut by the border, or no grid shape), False for
    none."""
    cv2 = require_cv2()
    try:
        found, grid = cv2.findChessboardCornersSB(gray, (3, 3), flags=cv2.CALIB_CB_LARGER)
    except cv2.error:
        return False
    if not found:
        return False
    pts = grid.reshape(-1, 2).astype(float)
    shape = _grid_shape(pts)
    if shape is None:
        return True
    g = _trim(gray, pts.reshape(shape[1], shape[0], 2))
    if g is None or min(g.shape[:2]) < 2:
        return True
    h, w = gray.shape
    margin = float(np.median(np.linalg.norm(np.diff(g, axis=1), axis=2)))
    flat = g.reshape(-1, 2)
    if (flat.min(axis=0) < margin).any() or flat[:, 0].max() > w - 1 - margin \
            or flat[:, 1].max() > h - 1 - margin:
        return True  # it may be a part of a larger board cut by the border
    return g.shape[1], g.shape[0]


def _grid_shape(pts: Array) -> tuple[int, int] | None:
    """``(cols, rows)`` of a grid listed row by row (a jump in the step between rows)."""
    if len(pts) < 9:
        return None
    step = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    jumps = np.flatnonzero(step > 1.8 * np.median(step))
    if jumps.size == 0:
        return None
    cols = int(jumps[0]) + 1
    if cols < 3 or len(pts) % cols:
        return None
    return cols, len(pts) // cols


def _trim(gray: NDArray[np.uint8], g: Array) -> Array | None:
    """The grid ``(rows, cols, 2)`` without outer rows and columns whose points are mostly
    no saddle (`SADDLE`)."""
    score = _saddle_scores(gray, g)
    while g.shape[0] >= 2 and g.shape[1] >= 2:
        edges = {"top": np.median(score[0]), "bottom": np.median(score[-1]),
                 "left": np.median(score[:, 0]), "right": np.median(score[:, -1])}
        worst = min(edges, key=edges.__getitem__)
        if edges[worst] >= SADDLE:
            return g
        cut = {"top": (slice(1, None), slice(None)), "bottom": (slice(None, -1), slice(None)),
               "left": (slice(None), slice(1, None)), "right": (slice(None), slice(None, -1))}
        g, score = g[cut[worst]], score[cut[worst]]
    return None


def _saddle_scores(gray: NDArray[np.uint8], g: Array) -> Array:
    """``|(a + b) - (c + d)| / (2 (max - min))`` of the grey levels a, b (one diagonal) and
    c, d (the other) a quarter of the grid step from every point ``(rows, cols)``: 1 where
    four squares meet, about 0.5 between a square and the white margin."""
    cv2 = require_cv2()
    ex = np.gradient(g, axis=1) if g.shape[1] > 1 else np.zeros_like(g)
    ey = np.gradient(g, axis=0) if g.shape[0] > 1 else np.zeros_like(g)
    offsets = (0.25 * (ex + ey), -0.25 * (ex + ey), 0.25 * (ex - ey), -0.25 * (ex - ey))
    img = gray.astype(np.float32)
    vals = []
    for o in offsets:
        p = (g + o).reshape(-1, 2).astype(np.float32)
        m = cv2.remap(img, p[:, 0].reshape(1, -1), p[:, 1].reshape(1, -1), cv2.INTER_LINEAR,
                      borderMode=cv2.BORDER_REPLICATE)
        vals.append(m.reshape(g.shape[:2]).astype(float))
    a, b, c, d = vals
    span = np.maximum.reduce(vals) - np.minimum.reduce(vals)
    return np.abs((a + b) - (c + d)) / np.maximum(2.0 * span, 1e-9)
