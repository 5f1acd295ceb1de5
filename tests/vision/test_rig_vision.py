"""Camera rigs on the vision side: ``--camera`` / ``--board NAME:LINK:SPEC`` parsing,
ChArUco boards told apart by their marker ids in one image, several boards rendered in one
image, the rig's STATIONS.csv (docs/rigs.md)."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal import load_model
from kinecal.calibration.handeye.camera import check_camera, project
from kinecal.errors import InputError
from kinecal.io.rig_stations import read_rig_stations, write_rig_stations
from kinecal.io.systems import load_machine
from kinecal.spatial import matrix_from_axis_angle, transform_from
from kinecal.vision.boards import parse_board
from kinecal.vision.imaging import ImageConditions, render_board, render_boards
from kinecal.vision.rig import Rig, RigBoard, RigCamera, is_mounted_board, parse_rig
from kinecal.vision.rig_images import complete_joints, detect_rig

K = np.array([[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]])
SIZE = (640, 480)
A = "charuco:5x4:30:22:DICT_5X5_100"
B = "charuco:5x4:30:22:DICT_5X5_100:10"


def test_charuco_first_id_round_trip_and_range():
    b = parse_board(B)
    assert b.spec == B and b.first == 10 and list(b.marker_ids) == list(range(10, 20))
    assert parse_board(A).spec == A  # no first id: the spec of before
    with pytest.raises(InputError, match="needs 10 markers from id 95"):
        parse_board("charuco:5x4:30:22:DICT_5X5_100:95")
    with pytest.raises(InputError, match="first marker id"):
        parse_board("charuco:5x4:30:22:DICT_5X5_100:-3")


def test_rig_specs_parsed_and_checked():
    rig = parse_rig(["left:world", "head:head"], [f"held:flange:{A}", f"table:world:{B}"])
    assert rig.camera_names == ["left", "head"] and rig.board_names == ["held", "table"]
    assert rig.told_apart()
    assert is_mounted_board(f"held:flange:{A}") and not is_mounted_board(A)
    with pytest.raises(InputError, match="same DICT_5X5_100 marker ids"):
        parse_rig(["c:world"], [f"a:flange:{A}", f"b:world:{A}"])
    with pytest.raises(InputError, match="given twice"):
        parse_rig(["c:world", "c:flange"], [f"a:flange:{A}"])
    with pytest.raises(InputError, match="NAME:LINK"):
        parse_rig(["c"], [f"a:flange:{A}"])
    with pytest.raises(InputError, match="NAME:LINK:SPEC"):
        parse_rig(["c:world"], ["a:flange"])
    with pytest.raises(InputError, match="link 'elbow'"):
        parse_rig(["c:elbow"], [f"a:flange:{A}"]).mounts(load_model("kr6-craig"))


def _two_board_image():
    ba, bb = parse_board(A), parse_board(B)
    Ta = transform_from(matrix_from_axis_angle([0.2, -0.1, 0.3]), [-160.0, -60.0, 560.0])
    Tb = transform_from(matrix_from_axis_angle([-0.2, 0.1, -0.2]), [40.0, -30.0, 520.0])
    img = render_boards([ba, bb], K, None, [Ta, Tb], SIZE, ImageConditions(blur=0.7, noise=1.5),
                        rng=3)
    return img, (ba, Ta), (bb, Tb)


def test_two_charuco_boards_in_one_image_told_apart():
    img, (ba, Ta), (bb, Tb) = _two_board_image()
    rig = Rig([RigCamera("c", "world")], [RigBoard("held", "flange", ba),
                                         RigBoard("other", "flange", bb)])
    views, _, skipped = detect_rig(rig, [img], ["i.png"], np.array([0]), np.zeros((1, 6)),
                                      [None], intrinsics=[_intrinsics()])
    assert not skipped and views.names == ["i.png"]
    d8 = check_camera(K, None)[1]
    for b, (board, T) in enumerate(((ba, Ta), (bb, Tb))):
        sel = views.board[0] == b
        assert sel.sum() == board.n_corners  # every corner of each board, none of the other
        P = views.points[0][sel]
        uv = project(K, d8, P @ T[:3, :3].T + T[:3, 3])
        assert np.abs(views.pixels[0][sel] - uv).max() < 0.3
        assert np.allclose(views.poses[0][b][:3, 3], T[:3, 3], atol=2.0)


def _intrinsics():
    from kinecal.vision.intrinsics import CameraIntrinsics

    return CameraIntrinsics(K, np.zeros(5), SIZE)


def test_render_boards_nearer_hides_farther_and_one_board_is_render_board():
    ba, bb = parse_board(A), parse_board(B)
    T = transform_from(np.eye(3), [-75.0, -60.0, 500.0])
    alone = render_board(ba, K, None, T, SIZE, rng=0)
    assert np.array_equal(alone, render_boards([ba], K, None, [T], SIZE, rng=0))
    behind = transform_from(np.eye(3), [40.0, -60.0, 900.0])  # the other board, farther
    both = render_boards([bb, ba], K, None, [behind, T], SIZE, rng=0)
    assert not np.array_equal(both, alone)  # the far board shows beside the near one
    # where the near board is, the image is the near board's alone
    x0, y0 = (project(K, np.zeros(8), ba.object_points[[0]] @ T[:3, :3].T + T[:3, 3])[0]
              .astype(int))
    box = (slice(y0 - 5, y0 + 40), slice(x0 - 5, x0 + 40))
    assert np.array_equal(both[box], alone[box])


def test_rig_stations_read_write_and_refusals(tmp_path):
    m = load_model("kr6-craig")
    q = np.radians([[0, -80, 90, 0, 30, 0], [10, -70, 80, 5, 20, 10]])
    p = tmp_path / "s.csv"
    write_rig_stations(p, m, ["a.png", "b.png"], ["left", "top"], q, ["held", None])
    st = read_rig_stations(p, m, ["top", "left"], ["held", "table"])
    assert st.names == ["a.png", "b.png"] and list(st.camera) == [1, 0]
    assert st.board == ["held", None] and np.allclose(st.q, q)
    bad = tmp_path / "bad.csv"
    bad.write_text("image,q1,q2,q3,q4,q5,q6\na.png,0,0,0,0,0,0\n")
    with pytest.raises(InputError, match="no camera column"):
        read_rig_stations(bad, m, ["left", "top"], ["held"])
    bad.write_text("image,camera,q1,q2,q3,q4,q5,q6\na.png,side,0,0,0,0,0,0\n")
    with pytest.raises(InputError, match=r"'side', expected one of the --camera names"):
        read_rig_stations(bad, m, ["left", "top"], ["held"])
    bad.write_text("image,camera,q1,q2,q3,q4,q5,q6\na.png,left,0,0,0,0,0,0\na.png,left,0,0,0,0,0,0\n")
    with pytest.raises(InputError, match="listed twice"):
        read_rig_stations(bad, m, ["left"], ["held"])
    one = tmp_path / "one.csv"  # one camera: the column may be left out
    one.write_text("image,q1,q2,q3,q4,q5,q6\na.png,0,-80,90,0,30,0\n")
    assert list(read_rig_stations(one, m, ["left"], ["held"]).camera) == [0]


def test_system_stations_blank_joints_the_images_do_not_need(tmp_path):
    cell = load_machine("head-arm")
    rig = parse_rig(["eye:head", "fixed:world"], ["held:arm:chessboard:9x6:25"])
    p = tmp_path / "s.csv"
    names = ",".join(cell.joint_names)
    p.write_text(f"image,camera,{names}\n"
                 "a.png,eye,0,-80,90,0,30,0,10,-5\n"
                 "b.png,fixed,0,-80,90,0,30,0,,\n")  # the static camera needs no head joint
    st = read_rig_stations(p, cell, rig.camera_names, rig.board_names)
    q = complete_joints(cell, rig, st.camera, st.board, st.q, st.names)
    assert np.isfinite(q).all() and np.allclose(q[0, -2:], np.radians([10, -5]))
    p.write_text(f"image,camera,{names}\na.png,eye,0,-80,90,0,30,0,,-5\n")
    st = read_rig_stations(p, cell, rig.camera_names, rig.board_names)
    with pytest.raises(InputError, match=r"joint head\.q1 is blank but moves its camera"):
        complete_joints(cell, rig, st.camera, st.board, st.q, st.names)


@pytest.mark.parametrize("spec, share", [("chessboard:7x5:25", 0.7), ("circles:5x5:20", 0.6)])
def test_turned_listings_told_from_the_robot_motions_alone(spec, share):
    """A symmetric board listed turned in most stations (more than the half a hand-eye
    RANSAC start tolerates), with both the camera and the board moving: the turns are told
    up to the board frame's own choice from the pairs' rotation angles, without X or Y."""
    from kinecal.spatial import invert_transform
    from kinecal.vision.turns import _turn_labels

    board = parse_board(spec)
    sym = board.symmetries()
    rng = np.random.default_rng(3)

    def pose(deg, mm):
        return transform_from(matrix_from_axis_angle(np.radians(deg) * _unit(rng)),
                              rng.normal(0, mm, 3))

    X, Y = pose(120, 300), pose(120, 300)
    H = np.array([pose(rng.uniform(5, 60), 200) for _ in range(12)])
    truth = np.where(rng.random(12) < share, rng.integers(1, len(sym) + 1, 12), 0)
    C = np.array([invert_transform(X) @ h @ Y @ pose(0.02, 0.05) for h in H])
    C = np.array([c if k == 0 else c @ sym[k - 1][0] for c, k in zip(C, truth, strict=True)])
    got = _turn_labels(H, C, board)
    m = len(sym) + 1

    def phase(k):  # the turn's multiple of 2 pi / m
        return 0 if k == 0 else round(np.arctan2(sym[k - 1][0][1, 0], sym[k - 1][0][0, 0])
                                      / (2 * np.pi / m)) % m

    rel = {(phase(g) - phase(t)) % m for g, t in zip(got, truth, strict=True)}
    assert len(rel) == 1, (got, truth)  # every station put back by the same global turn
    assert np.bincount(got).argmax() == 0  # the frame that leaves most stations as listed


def _unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)
