"""What a board detection returns and the thresholds it is judged by (shared by the
detectors of `kinecal.vision.detect` and `kinecal.vision.detect_circles`).

The edge width is the 10-90 % rise distance of the board's sharpest edges estimated as
``contrast / peak gradient * 0.78`` (a Gaussian-blurred step of sigma s gives 2.56 s; a
sharp, pixel-integrated edge about 1-1.5 px).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.vision import require_cv2
from kinecal.vision.board_base import Board
from kinecal.vision.pixels import percentiles_of_levels, upper_percentile

Array = NDArray[np.float64]

__all__ = ["Detection", "QualityLimits", "edge_width", "orientation_ambiguous"]


@dataclass
class QualityLimits:
    """Thresholds of the per-image checks.

    Attributes
    ----------
    max_edge_width : float
        Reject images whose board edges are wider than this (px, 10-90 % rise).
    min_corners : int or None
        Fewest corners accepted from boards that may be seen in part (ChArUco: ``kinecal
        handeye-images --min-corners``); default 60 % of the board's corners (at least 6):
        half a board is rejected, a view with a few occluded corners is not. Grid boards
        (chessboard, circle grids) are found whole or not at all.
    border : float
        Reject boards with a corner closer than this to the image border (px).
    max_tilt_deg : float
        Reject views where the board plane is tilted more than this from facing the
        camera (judged from the board pose).
    max_pnp_rms : float
        Reject images whose corners do not fit the board pose better than this (px RMS):
        a wrongly ordered or mis-detected grid.
    """

    max_edge_width: float = 4.5
    min_corners: int | None = None
    border: float = 3.0
    max_tilt_deg: float = 70.0
    max_pnp_rms: float = 3.0

    def corners_needed(self, board: Board) -> int:
        """The minimum corner count for `board`."""
        if self.min_corners is not None:
            return int(self.min_corners)
        return max(6, int(np.ceil(0.6 * board.n_corners)))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict."""
        return dict(self.__dict__)


@dataclass
class Detection:
    """Corners found in one image.

    Attributes
    ----------
    ok : bool
        Accepted for calibration.
    reason : str
        Why it was rejected ("" when accepted).
    corners : ndarray, shape (N, 2)
        Pixel positions (OpenCV convention) of the detected corners.
    ids : ndarray, shape (N,)
        Their corner ids (rows of `Board.object_points`).
    size : (int, int)
        Image width, height.
    edge_width : float
        Edge width of the board region (px), NaN when not measured.
    partial : bool
        Not every corner of the board was found (ChArUco).
    seen : str
        What the detector saw, in words (``"13 of 17 markers, 22 of 24 corners"``; ``""``
        when the whole board was found at once).
    """

    ok: bool
    reason: str
    corners: Array = field(default_factory=lambda: np.zeros((0, 2)))
    ids: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    size: tuple[int, int] = (0, 0)
    edge_width: float = float("nan")
    partial: bool = False
    seen: str = ""

    def reject(self, reason: str) -> Detection:
        """This detection, rejected for `reason` (corners kept for the report)."""
        self.ok = False
        self.reason = reason
        return self

    def object_points(self, board: Board) -> Array:
        """Board coordinates ``(N, 3)`` of the detected corners."""
        return board.object_points[self.ids]


def orientation_ambiguous(board: Board) -> bool:
    """True when `board` looks the same after a turn (a chessboard whose inner corner counts
    are both even or both odd, a symmetric circle grid), so its frame cannot be told from the
    image (`Board.symmetries`)."""
    return bool(board.symmetries())


def edge_width(gray: NDArray[np.uint8], mask: NDArray[np.bool_] | None = None) -> float:
    """10-90 % edge width (px) of the sharpest edges of `gray` (within `mask`).

    ``0.78 * contrast / peak gradient``, with the contrast between the 2nd and 98th
    intensity percentiles and the peak gradient the 99.5th percentile of the Sobel gradient
    magnitude; NaN when the region has no contrast.
    """
    cv2 = require_cv2()
    g = gray if gray.dtype == np.uint8 else gray.astype(np.float32)
    n = gray.size if mask is None else int(np.count_nonzero(mask))
    if n < 16:
        return float("nan")
    if gray.dtype == np.uint8:  # grey levels: the percentiles from their histogram
        m8 = None if mask is None else mask.view(np.uint8)
        counts = cv2.calcHist([g], [0], m8, [256], [0, 256]).ravel()
        lo, hi = percentiles_of_levels(counts, (2.0, 98.0))
    else:
        lo, hi = np.percentile(g[mask] if mask is not None else g, [2.0, 98.0])
    if hi - lo < 10.0:
        return float("nan")
    # the 3x3 Sobel / 8 (an exact scaling), its magnitude where the mask is (the squares
    # summed in place over the region, then one selection: the same float32 values)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    np.multiply(gx, gx, out=gx)
    np.multiply(gy, gy, out=gy)
    gx += gy
    m2 = gx[mask] if mask is not None else gx.ravel()
    peak = upper_percentile(np.sqrt(m2, out=m2), 99.5)
    if peak <= 0:
        return float("nan")
    return float(0.78 * (hi - lo) / peak)
