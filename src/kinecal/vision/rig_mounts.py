"""Where a simulated rig's cameras and boards sit: default mounts from the home
configuration.

At the home configuration every camera looks at a board on another link:

- a board on a moving link (a flange, a tip) is held 80 mm in front of it, its printed
  side facing out along the link's z axis;
- a static camera looks at its board's centre from the distance at which the board fills
  `fill` of its image width, from the board's printed side; several static cameras on one
  board look from directions tilted by `spread_deg` around the board's normal (a ring);
- a camera on a moving link looking at a board on another moving link (a head camera and
  a board in an arm's hand) sits 60 mm out along its link's z axis and looks at the
  board's centre;
- cameras on a moving link whose board is static (a wrist camera, a wrist stereo pair)
  hang as the one-camera renderer's eye-in-hand camera; a second camera on the same link
  sits `baseline` to its side, toed in; the static board then faces them at the viewing
  distance.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.camera.rig_frames import WORLD, LinkFrames
from kinecal.errors import InputError
from kinecal.spatial import invert_transform, matrix_from_axis_angle, transform_from
from kinecal.vision.boards import Board
from kinecal.vision.render import look_at

Array = NDArray[np.float64]

__all__ = ["default_mounts", "viewing_distance"]


def viewing_distance(board: Board, K: Array, size: tuple[int, int], fill: float) -> float:
    """Distance at which `board` spans `fill` of the image width (length unit)."""
    x0, y0, x1, y1 = board.extent()
    return float(K[0, 0] * max(x1 - x0, y1 - y0) / (fill * size[0]))


def _centre(board: Board) -> Array:
    x0, y0, x1, y1 = board.extent()
    return np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])


def _held(board: Board) -> Array:
    """A board 80 mm in front of its link, printed side out along the link's z."""
    R = matrix_from_axis_angle([0.0, np.pi, 0.2])
    return transform_from(R, np.array([0.0, 0.0, 80.0]) - R @ _centre(board))


def _ring(normal: Array, k: int, n: int, spread_deg: float) -> Array:
    """Direction `normal` tilted by `spread_deg` towards azimuth ``2 pi k / n``."""
    if n == 1:
        return normal
    a = np.cross(normal, [0.0, 0.0, 1.0])
    if np.linalg.norm(a) < 1e-6:
        a = np.cross(normal, [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    a = matrix_from_axis_angle(normal * (2 * np.pi * k / n)) @ a
    return matrix_from_axis_angle(a * np.radians(spread_deg)) @ normal


def _hand_camera(k: int, baseline: float, d0: float) -> Array:
    """The one-camera renderer's eye-in-hand mount; camera `k` of a pair `baseline` to the
    side of the first, toed in to meet its axis at `d0`."""
    X = transform_from(matrix_from_axis_angle([0.02, -0.03, np.pi / 2]), [70.0, -20.0, 60.0])
    if k == 0:
        return X
    b = baseline * k
    toe = matrix_from_axis_angle([0.0, -np.arctan2(b, d0), 0.0])
    return X @ transform_from(toe, [b, 0.0, 0.0])


def default_mounts(model, params: Array, q_home: Array, cameras: Sequence, boards: Sequence,
                   cams: Sequence[tuple[Array, tuple[int, int]]], *, fill: float = 0.55,
                   spread_deg: float = 25.0, baseline: float | None = None,
                   given: Mapping[str, Array] | None = None) -> tuple[list[Array], list[Array]]:
    """Camera mounts ``cam2link`` and board mounts ``board2link`` (module docstring).

    Parameters
    ----------
    model, params, q_home
        The true model, its parameters and the home configuration (rad).
    cameras, boards : sequence of Mount
        Resolved links; `boards` carry their `Board` as ``(mount, board)`` pairs.
    cams : sequence of (K, size)
        Each camera's matrix and image size.
    given : mapping, optional
        ``{"camera NAME" or "board NAME": (4, 4)}``: mounts to use as they are.
    """
    given = dict(given or {})
    links = [c.link for c in cameras] + [m.link for m, _ in boards]
    home = LinkFrames(model, np.atleast_2d(q_home), links).poses(params)

    def L(link: str) -> Array:
        return transform_from(home[link].R[0], home[link].t[0])

    Y: dict[int, Array] = {}
    X: dict[int, Array] = {}
    for b, (m, board) in enumerate(boards):
        if f"board {m.name}" in given:
            Y[b] = np.asarray(given[f"board {m.name}"], float)
        elif m.link != WORLD:
            Y[b] = _held(board)
    for c, m in enumerate(cameras):
        if f"camera {m.name}" in given:
            X[c] = np.asarray(given[f"camera {m.name}"], float)
    target = {c: next((b for b, (mb, _) in enumerate(boards) if mb.link != m.link), None)
              for c, m in enumerate(cameras)}
    if any(t is None for t in target.values()):
        bad = next(cameras[c].name for c, t in target.items() if t is None)
        raise InputError(f"camera {bad}: every board is on its own link, so it sees no "
                         "motion; mount a board elsewhere", option="--camera")
    for _ in range(3):
        _place_cameras(X, Y, cameras, boards, target, cams, L, fill, spread_deg)
        _place_static_boards(X, Y, cameras, boards, target, cams, L, fill, baseline)
    missing = [f"camera {cameras[c].name}" for c in range(len(cameras)) if c not in X] + \
        [f"board {boards[b][0].name}" for b in range(len(boards)) if b not in Y]
    if missing:  # pragma: no cover - every layout above places something
        raise InputError(f"could not place {', '.join(missing)}")
    return [X[c] for c in range(len(cameras))], [Y[b] for b in range(len(boards))]


def _place_cameras(X, Y, cameras, boards, target, cams, L, fill, spread_deg) -> None:
    """Cameras whose board is placed: static ones on a ring, moving ones from their link."""
    ring: dict[int, list[int]] = {}
    for c, m in enumerate(cameras):
        if m.link == WORLD:
            ring.setdefault(target[c], []).append(c)
    for c, m in enumerate(cameras):
        b = target[c]
        if c in X or b not in Y:
            continue
        mb, board = boards[b]
        B = L(mb.link) @ Y[b]
        centre = B[:3, :3] @ _centre(board) + B[:3, 3]
        out = -board.faces * B[:3, 2]  # the printed side's outward normal
        K, size = cams[c]
        if m.link == WORLD:
            k, n = ring[b].index(c), len(ring[b])
            eye = centre + viewing_distance(board, K, size, fill) * _ring(out, k, n, spread_deg)
            X[c] = look_at(eye, centre, 0.0)
        elif mb.link != WORLD:
            Lc = L(m.link)
            eye = Lc[:3, :3] @ np.array([0.0, 0.0, 60.0]) + Lc[:3, 3]
            X[c] = invert_transform(Lc) @ look_at(eye, centre, 0.0)


def _place_static_boards(X, Y, cameras, boards, target, cams, L, fill, baseline) -> None:
    """Static boards seen by cameras on a moving link: those cameras hang from their link
    (a pair side by side), the board faces the first at the viewing distance."""
    for b, (mb, board) in enumerate(boards):
        if b in Y:
            continue
        seeing = [c for c in range(len(cameras)) if target[c] == b]
        placed = [c for c in seeing if c in X]
        moving = [c for c in seeing if cameras[c].link != WORLD]
        if not placed and not moving:
            continue
        K, size = cams[(placed or moving)[0]]
        d0 = viewing_distance(board, K, size, fill)
        if not placed:
            first = cameras[moving[0]].link
            same = [c for c in moving if cameras[c].link == first]
            base = 0.25 * d0 if baseline is None else baseline
            for k, c in enumerate(same):
                X[c] = _hand_camera(k, base, d0)
            placed = same
        c0 = placed[0]
        C0 = transform_from(np.eye(3), np.array([0.0, 0.0, d0]) - _centre(board))
        Y[b] = invert_transform(L(mb.link)) @ L(cameras[c0].link) @ X[c0] @ C0
