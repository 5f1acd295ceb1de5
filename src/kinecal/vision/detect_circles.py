"""Detection of the circle grids (`kinecal.vision.circle_grids`).

Dots are found by OpenCV's blob detector (``cv2.SimpleBlobDetector``: dark, round, convex
blobs over a range of thresholds) and ordered into the grid by ``cv2.findCirclesGrid``
(``CALIB_CB_SYMMETRIC_GRID`` or ``CALIB_CB_ASYMMETRIC_GRID``; the symmetric grids are also
tried with the pattern size transposed and with ``CALIB_CB_CLUSTERING``, as
industrial_calibration's finder does). The blob detector is set for the image: areas from
8 px up to twice the image area per dot (OpenCV's default stops at 5000 px, a dot of 80 px),
circularity down to 0.6 and inertia ratio down to 0.1 (views tilted up to about 70 deg). A
grid that lists one blob twice (OpenCV issue 4775, which industrial_calibration's finder
also guards against) counts as not found.
The centres are the blobs' centroids, as OpenCV's: a projected circle's centroid lies off
the projection of its centre by a fraction of a pixel on oblique views (tests/vision
measures it on renders).

Ordering (the ids of `Board.object_points`):

- the grid is made right-handed in the image (ids ``r * COLS + c``: c to the right of r in a
  front view), the same rule for every board since the modified grid's ids run like text;
- a symmetric grid looks the same turned (`Board.symmetries`): of the labellings the turns
  allow, the one whose id 0 is nearest the image's top-left corner is taken, so the frame
  follows the view; the robot poses then settle it (`kinecal.vision.pipeline`);
- a modified grid is turned so that its origin dot, the corner dot at least 1.4 times as
  large as its two neighbours (2 times when printed as specified), gets the origin id; a view
  with no such dot, or with it where only a mirrored print would put it, is rejected.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.vision import require_cv2
from kinecal.vision.circle_grids import (
    AsymmetricCircleGrid,
    CircleGrid,
    ModifiedCircleGrid,
    SymmetricCircleGrid,
)
from kinecal.vision.detection import Detection, QualityLimits, edge_width

Array = NDArray[np.float64]

__all__ = ["blob_detector", "detect_circle_grid"]

#: a corner dot this many times larger than its neighbours is the modified grid's origin
ORIGIN_RATIO = 1.4


def blob_detector(shape: tuple[int, ...], board: CircleGrid) -> Any:
    """``cv2.SimpleBlobDetector`` for the dots of `board` in an image of `shape` (h, w)."""
    cv2 = require_cv2()
    p = cv2.SimpleBlobDetector_Params()
    p.filterByColor, p.blobColor = True, 0
    p.filterByArea, p.minArea = True, 8.0
    p.maxArea = float(max(5000.0, 2.0 * shape[0] * shape[1] / board.n_corners))
    p.filterByCircularity, p.minCircularity = True, 0.6
    p.filterByInertia, p.minInertiaRatio = True, 0.1
    p.filterByConvexity, p.minConvexity = True, 0.85
    return cv2.SimpleBlobDetector_create(p)


def _find_grid(gray: NDArray[np.uint8], board: CircleGrid, bd: Any) -> Array | None:
    """Dot centres ``(rows, cols, 2)`` as ``cv2.findCirclesGrid`` orders them, or None."""
    cv2 = require_cv2()
    cols, rows = board.cols, board.rows
    if isinstance(board, AsymmetricCircleGrid):
        found, c = cv2.findCirclesGrid(gray, (cols, rows), flags=cv2.CALIB_CB_ASYMMETRIC_GRID,
                                       blobDetector=bd)
        return c.reshape(rows, cols, 2).astype(float) if found else None
    sizes = [((cols, rows), False)] + ([((rows, cols), True)] if cols != rows else [])
    for extra in (0, cv2.CALIB_CB_CLUSTERING):
        for size, transposed in sizes:
            try:
                found, c = cv2.findCirclesGrid(gray, size, flags=cv2.CALIB_CB_SYMMETRIC_GRID
                                               | extra, blobDetector=bd)
            except cv2.error:
                found = False
            if found and c is not None and len(c) == cols * rows and _distinct(c):
                g = c.reshape(size[1], size[0], 2).astype(float)
                return g.transpose(1, 0, 2) if transposed else g
    return None


def _distinct(c: Array) -> bool:
    """No two grid points closer than a third of the median neighbour distance (OpenCV can
    list one blob twice, its issue 4775)."""
    c = c.reshape(-1, 2).astype(float)
    d = np.linalg.norm(c[:, None] - c[None], axis=2)
    np.fill_diagonal(d, np.inf)
    near = d.min(axis=1)
    return bool(near.min() > np.median(near) / 3.0)


def _right_handed(g: Array) -> Array:
    """The grid ``(rows, cols, 2)`` with its columns reversed when c and r turn clockwise
    the wrong way (a front view has c to the right of r in image coordinates)."""
    ex, ey = g[0, 1] - g[0, 0], g[1, 0] - g[0, 0]
    return g[:, ::-1] if ex[0] * ey[1] - ex[1] * ey[0] < 0 else g


def _canonical(c: Array, board: CircleGrid) -> Array:
    """Of the labellings a symmetric grid allows, the one with id 0 nearest the top left."""
    best = c
    for _, perm in board.symmetries():
        alt = np.empty_like(c)
        alt[perm] = c
        if alt[0].sum() < best[0].sum() - 1e-9:
            best = alt
    return best


def _dot_sizes(gray: NDArray[np.uint8], bd: Any, g: Array) -> Array:
    """Blob diameter ``(rows, cols)`` at every grid point (NaN where no blob matches)."""
    kp = bd.detect(gray)
    if not kp:
        return np.full(g.shape[:2], np.nan)
    pts = np.array([k.pt for k in kp])
    size = np.array([k.size for k in kp])
    flat = g.reshape(-1, 2)
    d = np.linalg.norm(flat[:, None] - pts[None], axis=2)
    j = np.argmin(d, axis=1)
    step = float(np.median(np.linalg.norm(np.diff(g, axis=1), axis=2)))
    out = np.where(d[np.arange(len(flat)), j] < 0.4 * step, size[j], np.nan)
    return out.reshape(g.shape[:2])


def _orient_modified(gray: NDArray[np.uint8], g: Array, board: ModifiedCircleGrid,
                     bd: Any) -> tuple[Array | None, str]:
    """The right-handed grid turned so that the origin dot sits at ``[rows - 1, 0]``; None
    and the reason when no corner dot stands out or the origin is where a mirror puts it."""
    s = _dot_sizes(gray, bd, g)
    R, C = g.shape[0] - 1, g.shape[1] - 1
    corners = {(R, 0): ((R, 1), (R - 1, 0)), (0, C): ((0, C - 1), (1, C)),
               (0, 0): ((0, 1), (1, 0)), (R, C): ((R, C - 1), (R - 1, C))}
    ratio = {k: s[k] / np.nanmean([s[a], s[b]]) for k, (a, b) in corners.items()}
    big = [k for k, v in ratio.items() if np.isfinite(v) and v >= ORIGIN_RATIO]
    seen = ", ".join(f"{v:.2f}" for v in ratio.values())
    if len(big) != 1:
        return None, (f"origin dot not found: the corner dots are {seen} times the size of "
                      f"their neighbours (the origin dot is twice the others' diameter)")
    k = big[0]
    if k == (0, C):
        return g[::-1, ::-1], ""
    if k == (R, 0):
        return g, ""
    if board.cols == board.rows:  # a quarter turn of the index grid keeps its handedness
        return np.rot90(g, 1 if k == (0, 0) else -1), ""
    return None, ("origin dot where only a mirrored print puts it (board printed mirrored, "
                  "or seen through from the back)")


def detect_circle_grid(gray: NDArray[np.uint8], board: CircleGrid, det: Detection,
                       limits: QualityLimits) -> Detection:
    """Find a whole circle grid in `gray`; `det` with the centres in id order, or rejected
    with what was seen (see the module docstring)."""
    bd = blob_detector(gray.shape, board)
    g = _find_grid(gray, board, bd)
    if g is None:
        w = edge_width(gray)
        if np.isfinite(w) and w > limits.max_edge_width:
            return det.reject(f"no board found; the image is blurred (edge width {w:.1f} px)")
        n = len(bd.detect(gray))
        det.seen = f"{n} dots"
        kind = "asymmetric circle grid" if isinstance(board, AsymmetricCircleGrid) else \
            "circle grid"
        if n < board.n_corners:
            return det.reject(f"no board found: {n} dots detected, the {board.cols}x"
                              f"{board.rows} {kind} has {board.n_corners} (partly visible, or "
                              "dots too small or blurred; circle grids are found whole)")
        return det.reject(f"no board found: {n} dots detected but no {board.cols}x"
                          f"{board.rows} {kind} among them (other dark blobs in view, a wrong "
                          "size in --board, or a strongly oblique view)")
    if isinstance(board, AsymmetricCircleGrid):
        c = g.reshape(-1, 2)
    elif isinstance(board, ModifiedCircleGrid):
        g, why = _orient_modified(gray, _right_handed(g), board, bd)
        if g is None:
            return det.reject(why)
        c = g.reshape(-1, 2)
    else:
        assert isinstance(board, SymmetricCircleGrid)
        c = _canonical(_right_handed(g).reshape(-1, 2), board)
    det.corners = np.ascontiguousarray(c, dtype=float)
    det.ids = np.arange(board.n_corners)
    return det
