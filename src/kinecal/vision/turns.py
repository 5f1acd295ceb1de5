"""Boards that look the same turned (a chessboard with two even or two odd counts, square
circle grids): their corners can be listed in a turned order, and the board frame is then
put back from the robot's motions (`turn_flipped`: one camera's images, from the rotation
angles of their pairs, synchronised over the board's turns); several cameras on one board
agree on its frame (`align_turns`); `warn_symmetric` says so up front.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kinecal import diagnostics
from kinecal.errors import InputError
from kinecal.vision.boards import Board
from kinecal.vision.results import ImageRecord

Array = NDArray[np.float64]

__all__ = ["align_turns", "turn_flipped", "warn_symmetric"]


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
                  C: Array, setup: str, method: str | None = None) -> int:
    """Symmetric boards: put back the stations whose corners were listed turned (board
    frame turned by one of `Board.symmetries`, e.g. 180 deg about the board centre).

    Decided without a hand-eye solution, from what it cannot change: the listed poses
    satisfy ``C_i = X^-1 H_i Y turn_i`` (``H_i`` the robot's motion, ``turn_i`` the unknown
    turn), so the relative motion ``C_i turn_d C_j^-1`` of two stations has the rotation
    angle of ``H_i H_j^-1`` only for their true relative turn ``d``; every pair votes
    for its ``d`` (weighted by how clearly it tells it), and the turns agreeing best with
    all votes are the phases of the leading eigenvector of the votes (synchronisation over
    the board's cyclic group; any share of the stations may be turned). The global turn is
    the board frame's choice: the one that leaves most stations as listed. `method` is
    not used (kept for callers). Returns how many were turned."""
    from kinecal.spatial import invert_transform

    G = F if setup == "eye-in-hand" else invert_transform(F)
    H = invert_transform(G)  # target2cam_i = X^-1 H_i Y
    T = np.array([r.pose.target2cam for r in (records[k] for k in used)])
    labels = _turn_labels(H, T, board)
    sym = board.symmetries()
    turned = 0
    for j, k in enumerate(used):
        if labels[j] == 0:
            continue
        _put_back(records[k], *sym[labels[j] - 1])
        turned += 1
    if turned:
        diagnostics.warn("board-turned",
                         f"{turned} image(s) of the symmetric board {board.spec} were listed "
                         "turned; their frame was turned back to agree with the robot poses "
                         "(use an asymmetric board to avoid the guess)")
    return turned


def _put_back(r: ImageRecord, turn: Array, perm: NDArray[np.intp]) -> None:
    """One image's corners and board pose put back from a turned listing."""
    from kinecal.spatial import invert_transform

    fixed = np.empty_like(r.detection.corners)
    fixed[perm] = r.detection.corners
    r.detection.corners = fixed
    r.pose.target2cam = r.pose.target2cam @ invert_transform(turn)
    res = np.empty_like(r.pose.residuals)
    res[perm] = r.pose.residuals
    r.pose.residuals = res


def align_turns(groups: list[tuple[list[ImageRecord], list[int], Array]],
                board: Board) -> int:
    """Several cameras on one symmetric board: each camera's images were put back among
    themselves (`turn_flipped`), each in a board frame of its own choice; turn every
    camera's to the frame of the camera with the most images.

    Parameters
    ----------
    groups : list of (records, used, F)
        Per camera: its records of the board, the used ones (indices), and ``F``
        ``(len(used), 4, 4)``: the board's link in the camera's link at those images (the
        nominal model), so that ``target2cam = X^-1 F Y``.
    board : Board

    Returns
    -------
    int
        Images turned. Each camera's ``Y`` (the board in its link) from a closed form: two
        cameras' differ by the turn between their frames.
    """
    from kinecal.calibration.handeye import robust_solve
    from kinecal.spatial import invert_transform, rotation_angle

    sym = board.symmetries()
    Ys = []
    for records, used, F in groups:
        try:
            C = np.array([records[k].pose.target2cam for k in used])
            Ys.append(robust_solve(invert_transform(F), C, "park")[1] if len(used) >= 3
                      else None)
        except InputError:  # no motion between the camera and the board: no Y
            Ys.append(None)
    placed = [g for g, Y in enumerate(Ys) if Y is not None]
    if not sym or len(placed) < 2:
        return 0
    ref = max(placed, key=lambda g: len(groups[g][1]))
    step = min(rotation_angle(T[:3, :3]) for T, _ in sym)
    turned = 0
    for g in placed:
        D = (invert_transform(Ys[ref]) @ Ys[g])[:3, :3]
        errs = [rotation_angle(T[:3, :3].T @ D) for T, _ in sym]
        best = int(np.argmin(errs))
        if rotation_angle(D) > step / 2 and errs[best] < step / 4:
            records, used, _ = groups[g]
            for k in used:
                _put_back(records[k], *sym[best])
            turned += len(used)
    if turned:
        diagnostics.warn("board-turned",
                         f"{turned} image(s) of the symmetric board {board.spec} were put "
                         "back in the board frame another camera saw (its frame turned "
                         "against that camera's)")
    return turned


def _turn_labels(H: Array, T: Array, board: Board) -> NDArray[np.intp]:
    """Per station the index into ``[identity] + board.symmetries()`` of the turn its
    corners were listed with (`turn_flipped`); 0 where the pairs cannot tell."""
    sym = board.symmetries()
    n, m = len(T), len(sym) + 1
    if n < 2 or m < 2:
        return np.zeros(n, np.intp)
    # the group: turns by 2 pi k / m about the board normal; element k of `turns`
    phase = [round(float(np.arctan2(t[1, 0], t[0, 0])) / (2 * np.pi / m)) % m
             for t, _ in sym]
    turns = [np.eye(4)] * m
    for t, (turn, _) in zip(phase, sym, strict=True):
        turns[t] = turn

    def angles(A: Array, B: Array) -> Array:
        """Rotation angles of every ``A_i B_j^T`` ``(n, n)`` (rad)."""
        return np.arccos(np.clip((np.einsum("iab,jab->ij", A, B) - 1.0) / 2.0, -1.0, 1.0))

    R = T[:, :3, :3]
    want = angles(H[:, :3, :3], H[:, :3, :3])
    errs = np.stack([np.abs(angles(R @ turns[d][:3, :3], R) - want) for d in range(m)])
    order = np.sort(errs, axis=0)
    weight = np.maximum(order[1] - 3.0 * order[0], 0.0)  # a clear winner only
    d = np.argmin(errs, axis=0)  # k_j - k_i
    votes = np.triu(weight * np.exp(-2j * np.pi * d / m), 1)
    votes += votes.conj().T
    z = np.linalg.eigh(votes)[1][:, -1]
    k = np.round(np.angle(z) / (2 * np.pi / m)).astype(np.intp) % m
    # no pair tells, or only pairs of another group of stations: as listed
    k[(np.abs(votes).sum(axis=1) == 0) | (np.abs(z) < 1e-6 * np.abs(z).max())] = -1
    known = k[k >= 0]
    if len(known) == 0:
        return np.zeros(n, np.intp)
    shift = int(np.argmax(np.bincount(known, minlength=m)))  # most stations as listed
    k = np.where(k >= 0, (k - shift) % m, 0)
    index = {t: i + 1 for i, t in enumerate(phase)}
    return np.array([0 if x == 0 else index[int(x)] for x in k], np.intp)
