"""Circle-grid boards: OpenCV's asymmetric and symmetric grids and industrial_calibration's
modified circle grid (a symmetric grid whose origin dot is larger).

Specs (``--board``):

- ``acircles:COLSxROWS:SPACING``: OpenCV's asymmetric circle grid (e.g. ``acircles:4x11:20``),
  circle ``(c, r)`` at ``((2 c + r mod 2) * SPACING, r * SPACING, 0)``, diameter SPACING.
- ``circles:COLSxROWS:PITCH[:DIAMETER]``: OpenCV's symmetric circle grid of COLS x ROWS dots
  (``cv2.findCirclesGrid`` with ``CALIB_CB_SYMMETRIC_GRID``), dot ``(c, r)`` with id
  ``r * COLS + c`` at ``(c * PITCH, r * PITCH, 0)``, frame as OpenCV's boards (z away from a
  camera that sees the print); DIAMETER defaults to 0.4 PITCH (OpenCV's pattern generator).
  The pattern looks the same turned by 180 deg (by 90 deg too when COLS = ROWS): the frame is
  put where the image suggests (id 0 nearest the image's top-left) and checked against the
  robot poses (`kinecal.vision.pipeline`).
- ``modcircles:COLSxROWS:PITCH[:DIAMETER]``: the modified circle grid of ROS-Industrial's
  industrial_calibration (``ModifiedCircleGridTarget``; e.g. ``modcircles:10x10:25.4``, its
  ``test_set_10x10``): a symmetric grid whose origin dot has twice the diameter (its target
  generator's ``dotTarget``), which fixes the orientation. Its definition, kept here so that
  board poses agree with industrial_calibration's: the origin dot is at the bottom left of
  the page, x runs along the bottom row to the right, y up the page, z out of the page
  (towards a camera that sees the print, unlike OpenCV's boards); ids run like text, left to
  right and top to bottom: id ``r * COLS + c`` sits at ``(c * PITCH, (ROWS - 1 - r) * PITCH,
  0)`` and the origin dot is id ``(ROWS - 1) * COLS``. DIAMETER (small dots) defaults to
  0.4 PITCH, the generator's default (10 mm dots 25 mm apart).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.vision.board_base import Board

Array = NDArray[np.float64]

__all__ = ["AsymmetricCircleGrid", "CircleGrid", "ModifiedCircleGrid", "SymmetricCircleGrid",
           "paint_dots"]

#: default dot diameter of the symmetric grids, in pitches
DEFAULT_DIAMETER = 0.4


def paint_dots(board: Board, px_per_unit: float, margin: float | None,
               centres: Array, diameters: Array) -> tuple[Any, Array]:
    """Texture (uint8) of black dots on white: each dot's pixels are covered by 4 x 4
    sub-samples (anti-aliased edges, grey level = covered fraction) within its bounding box.

    Parameters
    ----------
    board : Board
        Gives the texture frame (`Board._frame`).
    px_per_unit, margin
        As `Board.texture`.
    centres : ndarray, shape (n, 2)
        Dot centres (board frame, length unit).
    diameters : ndarray, shape (n,)
        Dot diameters (length unit).

    Returns
    -------
    image : ndarray, shape (h, w), uint8
    board2texture : ndarray, shape (3, 3)
    """
    w, h, A = board._frame(px_per_unit, margin)
    img = np.full((h, w), 255.0)
    sub = (np.arange(4) + 0.5) / 4.0 - 0.5  # sub-sample offsets within a pixel
    for (bx, by), d in zip(centres, diameters, strict=True):
        u, v = A[0, 0] * bx + A[0, 2], A[1, 1] * by + A[1, 2]  # texture pixel of the centre
        rad = 0.5 * d * px_per_unit
        j0, j1 = max(int(np.floor(u - rad)) - 1, 0), min(int(np.ceil(u + rad)) + 2, w)
        i0, i1 = max(int(np.floor(v - rad)) - 1, 0), min(int(np.ceil(v + rad)) + 2, h)
        if j0 >= j1 or i0 >= i1:
            continue
        su = (np.arange(j0, j1)[:, None] + sub[None, :]).ravel() - u
        sv = (np.arange(i0, i1)[:, None] + sub[None, :]).ravel() - v
        inside = (sv[:, None] ** 2 + su[None, :] ** 2) <= rad * rad
        cover = inside.reshape(i1 - i0, 4, j1 - j0, 4).mean(axis=(1, 3))
        img[i0:i1, j0:j1] = np.minimum(img[i0:i1, j0:j1], 255.0 * (1.0 - cover))
    return np.rint(img).astype(np.uint8), A


class CircleGrid(Board):
    """Common part of the circle grids: COLS x ROWS dots found by ``cv2.findCirclesGrid``."""

    cols: int
    rows: int

    def dot_diameters(self) -> Array:
        """Printed diameter ``(n_corners,)`` of every dot (length unit)."""
        raise NotImplementedError  # pragma: no cover

    def texture(self, px_per_unit: float, margin: float | None = None) -> tuple[Any, Array]:
        return paint_dots(self, px_per_unit, margin, self.object_points[:, :2],
                          self.dot_diameters())

    def extent(self) -> tuple[float, float, float, float]:
        P, r = self.object_points, 0.5 * self.dot_diameters()
        return (float((P[:, 0] - r).min()), float((P[:, 1] - r).min()),
                float((P[:, 0] + r).max()), float((P[:, 1] + r).max()))


def _check_grid(kind: str, cols: int, rows: int, least: tuple[int, int]) -> None:
    if cols < least[0] or rows < least[1]:
        raise InputError(f"{kind} {cols}x{rows}: expected at least {least[0]}x{least[1]} "
                         "circles", option="--board")


def _check_diameter(kind: str, diameter: float, pitch: float, limit: float) -> None:
    if not 0 < diameter < limit * pitch:
        raise InputError(f"{kind} dot diameter {diameter:g}: expected a positive diameter "
                         f"below {limit:g} x the pitch {pitch:g} (dots must not touch)",
                         option="--board")


@dataclass(frozen=True)
class AsymmetricCircleGrid(CircleGrid):
    """OpenCV's asymmetric circle grid: `cols` circles per row, `rows` rows."""

    cols: int
    rows: int
    spacing: float
    kind = "acircles"

    def __post_init__(self) -> None:
        _check_grid("acircles", self.cols, self.rows, (2, 3))

    @property
    def spec(self) -> str:
        return f"acircles:{self.cols}x{self.rows}:{self.spacing:g}"

    @property
    def pitch(self) -> float:
        return self.spacing

    def _object_points(self) -> Array:
        c, r = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        c, r = c.ravel(), r.ravel()
        return np.column_stack([(2 * c + r % 2) * self.spacing, r * self.spacing,
                                np.zeros(c.size)])

    def dot_diameters(self) -> Array:
        # diameter = spacing (diagonal neighbours are 1.41 spacings apart)
        return np.full(self.n_corners, self.spacing)


@dataclass(frozen=True)
class SymmetricCircleGrid(CircleGrid):
    """OpenCV's symmetric circle grid of ``cols x rows`` dots (see the module docstring)."""

    cols: int
    rows: int
    spacing: float
    diameter: float | None = None
    kind = "circles"

    def __post_init__(self) -> None:
        _check_grid("circles", self.cols, self.rows, (3, 3))
        _check_diameter("circles", self.dot, self.spacing, 1.0)

    @property
    def dot(self) -> float:
        """Dot diameter (length unit)."""
        return DEFAULT_DIAMETER * self.spacing if self.diameter is None else self.diameter

    @property
    def spec(self) -> str:
        tail = "" if self.diameter is None else f":{self.diameter:g}"
        return f"{self.kind}:{self.cols}x{self.rows}:{self.spacing:g}{tail}"

    @property
    def pitch(self) -> float:
        return self.spacing

    def _object_points(self) -> Array:
        c, r = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.column_stack([c.ravel() * self.spacing, r.ravel() * self.spacing,
                                np.zeros(c.size)])

    def dot_diameters(self) -> Array:
        return np.full(self.n_corners, self.dot)

    def symmetries(self) -> list[tuple[Array, NDArray[np.intp]]]:
        return self._turns(quarter=self.cols == self.rows)


@dataclass(frozen=True)
class ModifiedCircleGrid(SymmetricCircleGrid):
    """industrial_calibration's modified circle grid (see the module docstring): the
    symmetric grid with a marked origin dot, twice the others' diameter; ``dot`` is the
    small dots' diameter."""

    kind = "modcircles"
    faces = -1.0

    def __post_init__(self) -> None:
        _check_grid("modcircles", self.cols, self.rows, (3, 3))
        # the origin dot (twice the diameter) must not touch its neighbours
        _check_diameter("modcircles", self.dot, self.spacing, 2.0 / 3.0)

    @property
    def origin_id(self) -> int:
        """Id of the origin (large) dot: ``(rows - 1) * cols``."""
        return (self.rows - 1) * self.cols

    def _object_points(self) -> Array:
        c, r = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.column_stack([c.ravel() * self.spacing,
                                (self.rows - 1 - r.ravel()) * self.spacing,
                                np.zeros(c.size)])

    def symmetries(self) -> list[tuple[Array, NDArray[np.intp]]]:
        return []  # the origin dot marks the frame

    def dot_diameters(self) -> Array:
        d = np.full(self.n_corners, self.dot)
        d[self.origin_id] = 2.0 * self.dot
        return d
