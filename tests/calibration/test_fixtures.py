"""Known fixtures: points and planes whose position in the base frame is known
(kinecal.io.fixtures, the point and plane blocks' known groups). A MATE-like set: a
three-joint arm touching three planes at known x, y and z, as FIGAROH's MATE example."""

import dataclasses

import numpy as np
import pytest

from kinecal.calibration.blocks.api import calibrate_blocks
from kinecal.calibration.blocks.base import plane_constraint, point_constraint
from kinecal.calibration.blocks.plan import analyse_kinds
from kinecal.calibration.blocks.simulate import simulate_kind
from kinecal.calibration.serial.simulate import random_configurations, random_errors
from kinecal.kinematics.serial.model import SerialModel

BASE = ["base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz"]
#: three faces at known x, y and z (a point on each, its normal): the corner (350, 150, 100)
PLANES = np.array([[350.0, 0, 200, 1, 0, 0], [200, 150, 200, 0, 1, 0], [200, 0, 100, 0, 0, 1]])
#: the opposite face of the block, at x = -250
FACE = np.array([[-250.0, 0, 200, -1, 0, 0]])


def mate():
    """A three-joint arm with a base frame (the measurement frame is the fixture's) and a
    tool point."""
    joints = [dict(theta=0.0, d=300.0, a=50.0, alpha=np.pi / 2),
              dict(theta=0.0, d=0.0, a=250.0, alpha=0.0),
              dict(theta=0.0, d=0.0, a=200.0, alpha=0.0)]
    return SerialModel("mate", "dh", joints, base=[0.0] * 6, tool=[30.0, 10.0, 20.0],
                       joint_limits=[[-2.5, 2.5]] * 3,
                       tolerances={"length": 0.5, "angle": 0.005})


@pytest.fixture(scope="module")
def touches():
    m = mate()
    truth = m.nominal + random_errors(m, np.random.default_rng(1))
    sim = simulate_kind(m, "plane", 20, true_params=truth, planes=PLANES, rng=2)
    face = simulate_kind(m, "plane", 20, true_params=truth, planes=FACE, rng=3)
    known = dataclasses.replace(sim.data, known=sim.geometry["planes"])
    opposite = dataclasses.replace(face.data, group_names=("F4",),
                                   known=face.geometry["planes"])
    return m, truth, sim.data, known, opposite


def test_constraints_say_what_stays_put():
    rng = np.random.default_rng(0)
    c, n = rng.normal(size=3), np.array([0.0, 0.6, 0.8])
    # a rotation about an axis through c, and a scale about c, leave c where it is
    w, s = rng.normal(size=3), 0.3
    assert np.allclose(point_constraint(c) @ np.r_[-np.cross(w, c), w, 0.0], 0)
    assert np.allclose(point_constraint(c) @ np.r_[-s * c, 0, 0, 0, s], 0)
    assert not np.allclose(point_constraint(c) @ np.r_[1.0, 0, 0, 0, 0, 0, 0], 0)
    # a plane through c with normal n: moved within itself, turned about n, scaled about c
    t = np.cross(n, rng.normal(size=3))
    for m in (np.r_[t, 0, 0, 0, 0], np.r_[-np.cross(n, c), n, 0.0], np.r_[-s * c, 0, 0, 0, s]):
        assert np.allclose(plane_constraint(c, n) @ m, 0)
    assert not np.allclose(plane_constraint(c, n) @ np.r_[n, 0, 0, 0, 0], 0)


def test_known_planes_show_the_base_frame(touches):
    """Unknown planes see neither base frame nor scale; the same touches with the planes
    known see the base frame, and only the scale about the planes' corner stays unseen."""
    m, _, unknown, known, _ = touches
    a = analyse_kinds(m, [unknown])[0]
    b = analyse_kinds(m, [known])[0]
    assert set(BASE) <= set(a.report.unidentifiable)
    assert len(a.unseen) == 7 and a.shown_by_fixtures == []
    assert b.unseen == ["scale about (350, 150, 100)"]
    assert b.shown_by_fixtures == ["translation", "rotation"]
    # the base frame's rotation and two of its translations are free; the third trades
    # with the lengths in the unseen scale about the corner
    assert {"base.rx", "base.ry", "base.rz", "base.y", "base.z"} <= set(b.report.identifiable)
    assert b.report.rank == a.report.rank + 6


def test_mate_recovers_the_arm_up_to_the_unseen_scale(touches):
    m, truth, _, known, _ = touches
    res = calibrate_blocks(m, [known])
    q = random_configurations(m, 300, np.random.default_rng(9))
    P, Pt = res.model.positions(q), m.positions(q, truth)
    c = np.array([350.0, 150.0, 100.0])
    s = np.sum((Pt - c) * (P - c)) / np.sum((P - c) ** 2)
    assert np.linalg.norm(m.positions(q) - Pt, axis=1).max() > 1.0  # the arm's errors
    assert np.linalg.norm(P - Pt, axis=1).max() > 1e-3  # the scale is not seen ...
    # ... and is all that is left: noise-free touches, the true tool points after it
    assert np.linalg.norm(c + s * (P - c) - Pt, axis=1).max() < 1e-5


def test_a_fourth_known_face_shows_the_scale_and_recovers_the_truth(touches):
    m, truth, _, known, opposite = touches
    a = analyse_kinds(m, [known, opposite])[0]
    assert a.unseen == [] and a.shown_by_fixtures == ["translation", "rotation", "scale"]
    assert set(BASE) <= set(a.report.identifiable)
    res = calibrate_blocks(m, [known, opposite])
    assert res.free == a.report.identifiable
    q = random_configurations(m, 300, np.random.default_rng(9))
    assert np.linalg.norm(res.model.positions(q) - m.positions(q, truth), axis=1).max() < 1e-5
    # the held parameters (theta1, d1 behind base.rz, base.z ...) are at nominal: the free
    # ones took their errors, the base frame with a finite standard error
    assert np.isfinite(res.std[m.index(BASE)]).all() and (res.std[m.index(BASE)] < 1e-3).all()


def test_known_and_unknown_mix_in_one_file(touches):
    """Two planes known, the third solved with the arm: fewer unknowns, the third reported
    as solved, the known ones as given."""
    m, _, _, known, _ = touches
    k = np.array(known.known)
    k[2] = np.nan
    mixed = dataclasses.replace(known, known=k)
    res = calibrate_blocks(m, [mixed])
    [entry] = res.extra["kinds"]
    planes = {u["plane"]: u for u in entry["unknowns"]}
    assert [planes[g]["known"] for g in ("F1", "F2", "F3")] == [True, True, False]
    # the solved plane is the face at z = 100 (its normal's sign is the fit's choice) up
    # to what two known planes leave unseen: a translation along z, the scale
    assert res.extra["not_seen"] == ["scale about (350, 150, 0)", "translation z"]
    n, d = np.array(planes["F3"]["normal"]), planes["F3"]["offset"]
    np.testing.assert_allclose(n * np.sign(d), [0, 0, 1], atol=1e-6)
    assert planes["F1"]["offset"] == 350.0 and planes["F2"]["normal"] == [0.0, 1.0, 0.0]
    assert entry["unknowns"] and len(res.extra["kinds"][0]["unknowns"]) == 3
