"""`Board.object_points` is computed once per board and read-only: the detection, the
board pose and the refinement of every image ask for it (a ChArUco board's build OpenCV's
board each time otherwise)."""

import numpy as np
import pytest

from kinecal.vision.boards import parse_board

SPECS = ["chessboard:9x6:25", "charuco:7x5:35:26:DICT_5X5_100", "acircles:4x11:20",
         "circles:7x5:15", "modcircles:7x5:15:5"]


@pytest.mark.parametrize("spec", SPECS)
def test_object_points_once_and_read_only(spec):
    board = parse_board(spec)
    P = board.object_points
    assert P is board.object_points and P.dtype == float and P.shape == (board.n_corners, 3)
    assert np.array_equal(P, board._object_points())  # the computed values, unchanged
    with pytest.raises(ValueError):
        P[0, 0] = 1.0  # a caller cannot change the board for the next image
    again = parse_board(spec)
    assert again == board and hash(again) == hash(board)  # the cache is not a field


def test_chessboard_and_charuco_coordinates():
    P = parse_board("chessboard:9x6:25").object_points
    assert np.array_equal(P[[0, 1, 9, 53]], [[0, 0, 0], [25, 0, 0], [0, 25, 0], [200, 125, 0]])
    C = parse_board("charuco:7x5:35:26:DICT_5X5_100").object_points
    assert len(C) == 6 * 4 and np.allclose(C[0], [35, 35, 0]) and np.allclose(C[1], [70, 35, 0])
