"""Boards that look the same turned (a chessboard with two even or two odd counts, square
circle grids): their corners can be listed in a turned order, and the board frame is then
put back from the robot poses (`turn_flipped`); `warn_symmetric` says so up front.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.errors import InputError
from kinecal.vision.boards import Board
from kinecal.vision.results import ImageRecord

Array = NDArray[np.float64]

__all__ = ["turn_flipped", "warn_symmetric"]


def warn_symmetric(board: Board) -> None:
    turns = sorted({round(float(np.degrees(np.arctan2(T[1, 0], T[0, 0]))) % 360)
                    for T, _ in board.symmetries()})
    what = " and ".join(f"{a} deg" for a in turns)
    advice = ("use a board with one even and one odd count, or ChArUco"
              if board.kind == "chessboard" else
              "use a modcircles board (its origin dot fixes the frame), acircles or ChArUco")
    diagnostics.warn("board-symmetric",
                     f"{board.spec} looks the same turned by {what}: its frame can turn "
                     f"between images and is then put back from the robot poses; {advice}")


def turn_flipped(records: list[ImageRecord], used: list[int], board: Board, F: Array,
                  C: Array, setup: str, method: str) -> int:
    """Symmetric boards: put back the stations whose corners were listed turned (board
    frame turned by one of `Board.symmetries`, e.g. 180 deg about the board centre), judged
    by the pose the robot and a robust solution (RANSAC start: tolerates about half the
    stations turned) predict. Returns how many were turned."""
    from kinecal.calibration.handeye import robust_solve
    from kinecal.spatial import invert_transform, rotation_angle

    G = F if setup == "eye-in-hand" else invert_transform(F)
    try:
        X, Y = robust_solve(G, C, method)
    except InputError:  # degenerate motions: calibrate_handeye reports them next
        return 0
    pred = invert_transform(X) @ invert_transform(G) @ Y  # target2cam
    sym = board.symmetries()
    step = min(rotation_angle(T[:3, :3]) for T, _ in sym)  # smallest turn (pi or pi / 2)
    turned = 0
    for j, k in enumerate(used):
        r = records[k]
        T = r.pose.target2cam
        errs = [rotation_angle(pred[j, :3, :3].T @ (T @ invert_transform(turn))[:3, :3])
                for turn, _ in sym]
        best = int(np.argmin(errs))
        e0 = rotation_angle(pred[j, :3, :3].T @ T[:3, :3])
        if e0 > step / 2 and errs[best] < step / 4:
            turn, perm = sym[best]
            fixed = np.empty_like(r.detection.corners)
            fixed[perm] = r.detection.corners
            r.detection.corners = fixed
            r.pose.target2cam = T @ invert_transform(turn)
            res = np.empty_like(r.pose.residuals)
            res[perm] = r.pose.residuals
            r.pose.residuals = res
            turned += 1
    if turned:
        diagnostics.warn("board-turned",
                         f"{turned} image(s) of the symmetric board {board.spec} were listed "
                         "turned; their frame was turned back to agree with the robot poses "
                         "(use an asymmetric board to avoid the guess)")
    return turned
