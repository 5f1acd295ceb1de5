"""Calibration boards: geometry, printable texture and the ``--board`` syntax.

Every board has a frame with its origin on the board plane, x along the rows of corners,
y along the columns, z = x cross y (pointing away from a camera that sees the printed side,
as in OpenCV; industrial_calibration's modified circle grid is the exception, see
`kinecal.vision.circle_grids`), lengths in the unit of the spec (mm by convention). Corners
are numbered by an id; `Board.object_points` gives the board coordinates of every id.

Specs (``kinecal handeye-images --board``):

- ``chessboard:COLSxROWS:SQUARE``: COLS x ROWS *inner* corners (OpenCV's pattern size),
  squares of side SQUARE; e.g. ``chessboard:9x6:30`` (10 x 7 squares of 30 mm). Corner
  ``(c, r)`` has id ``r * COLS + c`` and sits at ``(c * SQUARE, r * SQUARE, 0)``; the
  square diagonally outside corner 0 is black. Boards with COLS + ROWS odd (one count even,
  one odd, as 9x6) have a unique orientation; others look the same turned by 180 deg.
- ``charuco:COLSxROWS:SQUARE:MARKER:DICT[:FIRST]``: ChArUco board of COLS x ROWS *squares*,
  square and marker sides in the length unit, an OpenCV ArUco dictionary name, e.g.
  ``charuco:7x5:40:30:DICT_5X5_100`` (OpenCV's layout and corner ids; origin at the outer
  corner of the board). ``FIRST``: the id of its first marker (default 0; its markers are
  FIRST, FIRST + 1, ...): several boards of one dictionary with disjoint id ranges are told
  apart in one image (``charuco:7x5:40:30:DICT_5X5_100:20`` is a second board after a
  first one's 17 markers).
- ``acircles:COLSxROWS:SPACING``, ``circles:COLSxROWS:PITCH[:DIAMETER]`` and
  ``modcircles:COLSxROWS:PITCH[:DIAMETER]``: circle grids (`kinecal.vision.circle_grids`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.vision.board_base import SYNTAX, Board, grid_size, positive_length
from kinecal.vision.circle_grids import (
    AsymmetricCircleGrid,
    ModifiedCircleGrid,
    SymmetricCircleGrid,
)

Array = NDArray[np.float64]

__all__ = ["AsymmetricCircleGrid", "Board", "Charuco", "Chessboard", "ModifiedCircleGrid",
           "SymmetricCircleGrid", "parse_board"]


@dataclass(frozen=True)
class Chessboard(Board):
    """Chessboard of ``cols x rows`` inner corners and square side `square`."""

    cols: int
    rows: int
    square: float
    kind = "chessboard"

    def __post_init__(self) -> None:
        if self.cols < 3 or self.rows < 3:  # OpenCV's detector needs 3 each way
            raise InputError(f"chessboard {self.cols}x{self.rows}: expected at least 3x3 inner "
                             "corners", option="--board")

    @property
    def spec(self) -> str:
        return f"chessboard:{self.cols}x{self.rows}:{self.square:g}"

    @property
    def symmetric(self) -> bool:
        """True when the board looks the same turned by 180 deg (cols + rows even)."""
        return (self.cols + self.rows) % 2 == 0

    @property
    def pitch(self) -> float:
        return self.square

    def symmetries(self) -> list[tuple[Array, NDArray[np.intp]]]:
        """The half turn when the board is `symmetric` (its colours do not tell the ends)."""
        return self._turns(quarter=False) if self.symmetric else []

    def _object_points(self) -> Array:
        c, r = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.column_stack([c.ravel() * self.square, r.ravel() * self.square,
                                np.zeros(c.size)])

    def extent(self) -> tuple[float, float, float, float]:
        s = self.square
        return -s, -s, self.cols * s, self.rows * s

    def texture(self, px_per_unit: float, margin: float | None = None) -> tuple[Any, Array]:
        w, h, A = self._frame(px_per_unit, margin)
        # board coordinates of every texture pixel centre
        x = (np.arange(w) - A[0, 2]) / px_per_unit
        y = (np.arange(h) - A[1, 2]) / px_per_unit
        i = np.floor(x / self.square).astype(int) + 1  # square column 0 .. cols
        j = np.floor(y / self.square).astype(int) + 1
        inside = ((i >= 0) & (i <= self.cols))[None, :] & ((j >= 0) & (j <= self.rows))[:, None]
        black = ((i[None, :] + j[:, None]) % 2 == 0) & inside
        return np.where(black, 0, 255).astype(np.uint8), A


@dataclass(frozen=True)
class Charuco(Board):
    """ChArUco board of ``cols x rows`` squares (OpenCV's ``cv2.aruco.CharucoBoard``)."""

    cols: int
    rows: int
    square: float
    marker: float
    dictionary: str
    first: int = 0
    kind = "charuco"

    def __post_init__(self) -> None:
        if self.cols < 3 or self.rows < 3:
            raise InputError(f"charuco {self.cols}x{self.rows}: expected at least 3x3 squares",
                             option="--board")
        if not self.marker < self.square:
            raise InputError(f"charuco marker {self.marker:g} must be smaller than the square "
                             f"{self.square:g}", option="--board")
        from kinecal.vision import require_cv2

        cv2 = require_cv2()
        if not self.dictionary.startswith("DICT_") or not hasattr(cv2.aruco, self.dictionary):
            names = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
            raise InputError(f"unknown ArUco dictionary {self.dictionary!r}; expected one of "
                             f"{', '.join(names)}", option="--board")
        size = int(re.search(r"_(\d+)$", self.dictionary).group(1)) \
            if re.search(r"_(\d+)$", self.dictionary) else 10**9
        needed = self.n_markers
        if self.first < 0:
            raise InputError(f"charuco first marker id {self.first}: expected 0 or more",
                             option="--board")
        if self.first + needed > size:
            at = f" from id {self.first}" if self.first else ""
            raise InputError(f"charuco {self.cols}x{self.rows} needs {needed} markers{at} but "
                             f"{self.dictionary} has {size}", option="--board")

    @property
    def spec(self) -> str:
        return (f"charuco:{self.cols}x{self.rows}:{self.square:g}:{self.marker:g}:"
                f"{self.dictionary}" + (f":{self.first}" if self.first else ""))

    @property
    def n_markers(self) -> int:
        """Number of ArUco markers on the board (every other square)."""
        return (self.cols * self.rows) // 2

    @property
    def marker_ids(self) -> range:
        """The ids of its markers: ``first .. first + n_markers - 1``."""
        return range(self.first, self.first + self.n_markers)

    @property
    def pitch(self) -> float:
        return self.square

    def cv_board(self) -> Any:
        """The ``cv2.aruco.CharucoBoard``."""
        from kinecal.vision import require_cv2

        cv2 = require_cv2()
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        if not self.first:
            return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square, self.marker, d)
        ids = np.arange(self.first, self.first + self.n_markers, dtype=np.int32)
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square, self.marker, d, ids)

    def _object_points(self) -> Array:
        return np.asarray(self.cv_board().getChessboardCorners(), dtype=float).reshape(-1, 3)

    def extent(self) -> tuple[float, float, float, float]:
        return 0.0, 0.0, self.cols * self.square, self.rows * self.square

    def texture(self, px_per_unit: float, margin: float | None = None) -> tuple[Any, Array]:
        w, h, A = self._frame(px_per_unit, margin)
        m = self.pitch if margin is None else float(margin)
        # OpenCV draws the board into the inner area; render it at an integer pixel size
        # per square, then place it with its own scale (exact placement of the corners)
        pps = max(round(float(self.square * px_per_unit)), 8)
        inner = self.cv_board().generateImage((self.cols * pps, self.rows * pps), marginSize=0,
                                              borderBits=1)
        from kinecal.vision import require_cv2

        cv2 = require_cv2()
        s = px_per_unit * self.square / pps
        M = np.array([[s, 0.0, m * px_per_unit + 0.5 * s - 0.5],
                      [0.0, s, m * px_per_unit + 0.5 * s - 0.5]])
        img = cv2.warpAffine(inner, M, (w, h), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=255)
        return img, A


def parse_board(spec: str) -> Board:
    """Board from its ``--board`` spec (see the module docstring).

    Raises
    ------
    InputError
        Unknown kind, bad sizes or lengths, unknown dictionary (option ``--board``).
    """
    parts = [p.strip() for p in str(spec).split(":")]
    kind = parts[0].lower()
    if kind == "chessboard" and len(parts) == 3:
        c, r = grid_size(parts[1])
        return Chessboard(c, r, positive_length(parts[2], "square"))
    if kind == "charuco" and len(parts) in (5, 6):
        c, r = grid_size(parts[1])
        first = _first_id(parts[5]) if len(parts) == 6 else 0
        return Charuco(c, r, positive_length(parts[2], "square"),
                       positive_length(parts[3], "marker"), parts[4].upper(), first)
    if kind == "acircles" and len(parts) == 3:
        c, r = grid_size(parts[1])
        return AsymmetricCircleGrid(c, r, positive_length(parts[2], "spacing"))
    grids = {"circles": SymmetricCircleGrid, "modcircles": ModifiedCircleGrid}
    if kind in grids and len(parts) in (3, 4):
        c, r = grid_size(parts[1])
        dot = positive_length(parts[3], "dot diameter") if len(parts) == 4 else None
        return grids[kind](c, r, positive_length(parts[2], "pitch"), dot)
    raise InputError(f"board {spec!r}: expected {SYNTAX}", option="--board")


def _first_id(text: str) -> int:
    """The first marker id of a ChArUco spec: an integer 0 .. 100000."""
    if not text.isdigit() or int(text) > 100_000:
        raise InputError(f"charuco first marker id {text!r}: expected an integer 0 or more "
                         "(the id of the board's first marker)", option="--board")
    return int(text)
