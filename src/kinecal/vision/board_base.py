"""The interface every calibration board implements, and the parsing helpers of the specs.

A board has a frame with its origin on the board plane (z = 0), corner ids with board
coordinates (`Board.object_points`, length unit of the spec), a printable texture for the
renderer, the side its pattern is printed on (`Board.faces`) and the turns of its frame that
the pattern cannot tell apart (`Board.symmetries`). The boards themselves are in
`kinecal.vision.boards` (chessboard, ChArUco) and `kinecal.vision.circle_grids`.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError

Array = NDArray[np.float64]

__all__ = ["MAX_GRID", "SYNTAX", "Board", "grid_size", "positive_length"]

SYNTAX = ("chessboard:COLSxROWS:SQUARE (inner corners, e.g. chessboard:9x6:30), "
          "charuco:COLSxROWS:SQUARE:MARKER:DICT[:FIRST] (squares, e.g. "
          "charuco:7x5:40:30:DICT_5X5_100; FIRST: the first marker id), "
          "acircles:COLSxROWS:SPACING (e.g. acircles:4x11:20), "
          "circles:COLSxROWS:PITCH[:DIAMETER] (e.g. circles:7x6:20) "
          "or modcircles:COLSxROWS:PITCH[:DIAMETER] (e.g. modcircles:10x10:25.4)")


#: most corners (squares for ChArUco, dots for circle grids) a board spec may have: 50 x 50
#: (printed boards have tens to a few hundred; a 3000 x 3000 spec asked for petabytes)
MAX_GRID = 2500


class Board:
    """Common interface of the boards (see the module docstring)."""

    kind: str = ""
    #: +1: the pattern is seen from the board's -z side (OpenCV's boards: z points away from a
    #: camera that sees the print); -1: seen from +z (industrial_calibration's modified
    #: circle grid: z comes out of the page)
    faces: float = 1.0

    @property
    def spec(self) -> str:  # pragma: no cover - overridden
        raise NotImplementedError

    @property
    def n_corners(self) -> int:
        """Number of corner ids."""
        return len(self.object_points)

    @property
    def object_points(self) -> Array:
        """Board coordinates ``(n_corners, 3)`` of every corner id (z = 0), read-only.

        Computed once per board (`_object_points`): every image's detection, board pose and
        refinement asks for them, and a ChArUco board's come from building OpenCV's board.
        """
        cached = self.__dict__.get("_points")
        if cached is None:
            cached = np.asarray(self._object_points(), dtype=float)
            cached.setflags(write=False)
            object.__setattr__(self, "_points", cached)  # the boards are frozen dataclasses
        return cached

    def _object_points(self) -> Array:  # pragma: no cover - overridden
        """The board coordinates `object_points` returns, computed."""
        raise NotImplementedError

    @property
    def pitch(self) -> float:
        """Distance between neighbouring corners (length unit)."""
        raise NotImplementedError  # pragma: no cover

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` of the printed pattern (board frame, no margin)."""
        raise NotImplementedError  # pragma: no cover

    def symmetries(self) -> list[tuple[Array, NDArray[np.intp]]]:
        """Turns of the board frame that map the pattern onto itself so that a detector may
        list the corners from another end (none for boards with a marked origin).

        Returns
        -------
        list of (turn, perm)
            ``turn`` ``(4, 4)``: the turn in the board frame (about the pattern's centre);
            ``perm`` ``(n_corners,)``: corner i is moved onto corner ``perm[i]``. A view whose
            corners were listed turned has the board pose ``T_listed @ inv(turn)`` and the
            corrected list ``c'[perm] = c``.
        """
        return []

    def texture(self, px_per_unit: float, margin: float | None = None) -> tuple[Any, Array]:
        """Image of the printed board (uint8, white margin) and its placement.

        Parameters
        ----------
        px_per_unit : float
            Texture resolution, pixels per length unit.
        margin : float, optional
            White quiet zone around the pattern (length unit); default one pitch.

        Returns
        -------
        image : ndarray, shape (h, w), uint8
        board2texture : ndarray, shape (3, 3)
            Maps board ``(x, y, 1)`` to texture pixel coordinates (OpenCV convention:
            integer coordinates are pixel centres).
        """
        raise NotImplementedError  # pragma: no cover

    def _frame(self, px_per_unit: float, margin: float | None) -> tuple[int, int, Array]:
        m = self.pitch if margin is None else float(margin)
        x0, y0, x1, y1 = self.extent()
        x0, y0, x1, y1 = x0 - m, y0 - m, x1 + m, y1 + m
        w = int(np.ceil((x1 - x0) * px_per_unit))
        h = int(np.ceil((y1 - y0) * px_per_unit))
        A = np.array([[px_per_unit, 0.0, -x0 * px_per_unit - 0.5],
                      [0.0, px_per_unit, -y0 * px_per_unit - 0.5],
                      [0.0, 0.0, 1.0]])
        return w, h, A

    def _turns(self, quarter: bool) -> list[tuple[Array, NDArray[np.intp]]]:
        """The half turn (and the quarter turns) about the centre of the corner grid, with
        the corner permutations they induce (nearest corner after the turn)."""
        P = self.object_points
        c = 0.5 * (P.min(axis=0) + P.max(axis=0))
        out = []
        for k in ((1, 2, 3) if quarter else (2,)):
            a = 0.5 * np.pi * k
            R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0],
                          [0.0, 0.0, 1.0]])
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, c - R @ c
            moved = P @ R.T + T[:3, 3]
            perm = np.argmin(np.linalg.norm(moved[:, None] - P[None], axis=2), axis=1)
            out.append((T, perm.astype(np.intp)))
        return out

    def to_dict(self) -> dict[str, Any]:
        """``{"spec", "kind", "corners", "pitch"}``."""
        return {"spec": self.spec, "kind": self.kind, "corners": self.n_corners,
                "pitch": self.pitch}


def grid_size(spec: str) -> tuple[int, int]:
    """``COLSxROWS`` -> ``(cols, rows)``; `InputError` (option ``--board``) otherwise."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", spec)
    if m is None:
        raise InputError(f"board size {spec!r}: expected COLSxROWS, e.g. 9x6; {SYNTAX}",
                         option="--board")
    c, r = int(m.group(1)), int(m.group(2))
    if c * r > MAX_GRID:
        raise InputError(f"board size {spec!r}: {c * r:,} corners or squares, expected at most "
                         f"{MAX_GRID:,} (a board's corner count is a few hundred)",
                         option="--board")
    return c, r


#: board lengths outside this range are no printed board's in any length unit (a 1 um
#: square in metres, 1000 km in millimetres), and their products overflow
LENGTH_RANGE = (1e-6, 1e6)


def positive_length(text: str, what: str) -> float:
    """A positive finite length from the spec (within `LENGTH_RANGE`); `InputError` naming
    `what` otherwise."""
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (np.isfinite(v) and v > 0):
        raise InputError(f"board {what} {text!r}: expected a positive length; {SYNTAX}",
                         option="--board")
    lo, hi = LENGTH_RANGE
    if not lo <= v <= hi:
        raise InputError(f"board {what} {text!r}: implausible for a printed board (expected "
                         f"{lo:g} to {hi:g} in the length unit of the robot poses or model, "
                         "e.g. 25 for 25 mm squares)", option="--board")
    return v
