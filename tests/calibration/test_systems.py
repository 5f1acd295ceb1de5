"""Calibration of robot systems on the stacked problem (kinecal.calibration.blocks):
recovery of a known truth for TALOS's torso and both arms (tracker), two UR5 with a bar
between the hands, a UR10 on a rail beside a two-axis positioner touched by a probe; noisy
held-out errors per chain at the noise floor; shared torso parameters that agree whichever
chain's data are added; what each chain identifies alone and what only the combination
does; errors per tip in the result JSON."""

import importlib.metadata

import numpy as np
import pytest

import kinecal
from kinecal.calibration.blocks.api import calibrate_system
from kinecal.calibration.blocks.plan import analyse_system
from kinecal.calibration.blocks.system_simulate import simulate_system
from kinecal.io.systems import load_machine
from kinecal.io.urdf_tree import load_urdf_system

WORKPIECE = [[150, 0, 30], [0, 150, 30], [-120, -80, 30], [60, -140, 30]]


def talos():
    dist = importlib.metadata.distribution("example-robot-data")
    path = dist.locate_file("cmeel.prefix/share/example-robot-data/robots/"
                            "talos_data/robots/talos_reduced.urdf")
    system = load_urdf_system(path, ["gripper_left_base_link", "gripper_right_base_link"])
    p = system.nominal
    left, right = system.tips  # tracker targets off the grippers' axes
    p[system.index([f"{left}.tool.x", f"{right}.tool.x", f"{left}.tool.z",
                    f"{right}.tool.z"])] = [0.02, -0.02, -0.1, -0.1]
    return system.with_params(p)


def truth(system, make, seed, length=1e-3, angle=1e-3):
    """A true system (the nominal with errors on the parameters the nominal system's data
    identify) and its data: ``make(params)`` gives the data sets of a system."""
    ana, _, _ = analyse_system(system, make(system.nominal))
    idx = system.index(ana.report.identifiable)
    rng = np.random.default_rng(seed)
    p = system.nominal
    p[idx] += rng.uniform(-1, 1, idx.size) * np.where(system.is_angle()[idx], angle, length)
    return p, ana.report.identifiable, make(p)


def test_talos_torso_and_both_arms_recover_to_round_off():
    system = talos()
    true, free, (cal,) = truth(system, lambda p: [simulate_system(
        system, 40, true_params=p, rng=3).data], 2)
    val = simulate_system(system, 30, true_params=true, rng=4).data
    res = calibrate_system(system, cal, validate=val)
    assert res.free == free
    assert np.abs(res.params - true).max() < 1e-10  # m and rad
    assert res.val_after.max() < 1e-12  # m
    shared = set(system.shared_parameters())
    assert {"torso_2_joint.offset", "torso_2_joint.x"} <= shared & set(res.free)
    out = res.to_dict()
    for section in ("calibration", "validation"):
        tips = out[section]["by_tip"]
        assert set(tips) == set(system.tips)
        assert sum(t["n"] for t in tips.values()) == out[section]["n"]
        assert all(t["after"]["max"] < 1e-12 for t in tips.values())
        assert {"mean", "rms", "max"} <= set(tips[system.tips[0]]["before"])


def test_dual_ur5_with_a_bar_between_the_hands():
    system = load_machine("dual-ur5")

    def make(p):
        return [simulate_system(system, 25, true_params=p, rng=4).data,
                simulate_system(system, 15, kind="pair", tips=["left", "right"], length=300.0,
                                true_params=p, rng=5).data]

    true, free, (arms, bar) = truth(system, make, 3, length=0.3, angle=2e-3)
    assert set(bar.marker[0::2]) == {0} and set(bar.marker[1::2]) == {1}  # hand to hand
    res = kinecal.calibrate(system, [arms, bar])  # the API takes a system to the stack
    assert res.free == free
    assert np.abs(res.params - true).max() < 1e-8  # mm, rad
    assert res.errors_after.max() < 1e-8
    pair = res.extra["kinds"][1]
    assert pair["kind"] == "pair" and pair["after"]["max"] < 1e-8
    by_tip = res.extra["by_tip"]["calibration"]  # a bar counts for both hands
    assert by_tip["left"]["n"] == by_tip["right"]["n"] == 25 + 15


def rail_cell_data(true, n_tracker, n_touch, seed, noise=0.0, touch_noise=0.0):
    system = load_machine("rail-cell")
    tracker = simulate_system(system, n_tracker, tips=["rail", "arm"], true_params=true,
                              noise=noise, rng=seed).data
    touches = simulate_system(system, n_touch, kind="point", tips=["arm"],
                              carrier="positioner", centres=WORKPIECE, true_params=true,
                              noise=touch_noise, rng=seed + 1).data
    return system, tracker, touches


def test_rail_and_positioner_from_probe_touches():
    system = load_machine("rail-cell")
    true, free, (tracker, touches) = truth(
        system, lambda p: rail_cell_data(p, 30, 6, 3)[1:], 2, length=0.3, angle=1e-3)
    res = calibrate_system(system, [tracker, touches])
    assert res.free == free
    assert np.abs(res.params - true).max() < 1e-8
    assert res.errors_after.max() < 1e-8  # mm
    # the positioner has no tracker rows: the probe's touches see it, with the arm's chain
    section = res.extra["system"]
    positioner = [n for n in res.free if n.startswith("positioner.")]
    assert len(positioner) >= 6 and set(positioner) <= set(section["combination_only"])
    assert section["tips"]["positioner"]["rows"] == 0
    points = res.extra["kinds"][1]["unknowns"]
    assert {p["frame"] for p in points} == {"positioner"}
    np.testing.assert_allclose([p["xyz"] for p in points], WORKPIECE, atol=1e-8)


def test_noisy_held_out_errors_of_every_chain_at_the_noise_floor():
    sigma = 0.02
    system = load_machine("rail-cell")
    true = system.nominal + np.random.default_rng(7).uniform(-1, 1, system.n_params) * \
        np.where(system.is_angle(), 2e-3, 0.5) * np.isin(system.parameter_names,
                                                         system.calibratable)
    _, tracker, touches = rail_cell_data(true, 150, 10, 8, sigma, sigma)
    _, val, _ = rail_cell_data(true, 100, 1, 20, sigma)
    res = calibrate_system(system, [tracker, touches], validate=[val])
    exact = np.linalg.norm(system.positions(val.q, true, val.marker) - val.xyz, axis=1)
    by_tip = res.to_dict()["validation"]["by_tip"]
    for tip in ("rail", "arm"):  # the calibrated system within 5 % of the true one's error
        floor = float(np.sqrt(np.mean(exact[val.marker == system.tip_number(tip)] ** 2)))
        assert by_tip[tip]["after"]["rms"] < 1.05 * floor, (tip, by_tip[tip], floor)
        assert by_tip[tip]["before"]["rms"] > 10 * floor  # the errors were there


def test_shared_torso_parameters_agree_whichever_arm_is_added():
    """The torso's parameters the left arm's rows identify, estimated from those rows and
    from those and the right arm's (its parameters freed as far as the two identify them):
    the estimates agree within their uncertainty, and the second is no less certain."""
    system = talos()
    sigma = 2e-5  # m
    left_tip = system.tips[0]

    def make(p):
        return [simulate_system(system, 120, tips=[tip], true_params=p, noise=sigma,
                                rng=6 + k).data for k, tip in enumerate(system.tips)]

    _, _, (left, right) = truth(system, make, 5)
    free_left = analyse_system(system, [left])[0].report.identifiable
    right_only = [n for n in system.calibratable
                  if n not in system.chain_parameters(left_tip)]
    both = analyse_system(system, [left, right], free_left + right_only)[0]
    one = calibrate_system(system, [left], sigma=sigma, free=free_left)
    two = calibrate_system(system, [left, right], sigma=sigma, free=both.report.identifiable)
    torso = [n for n in free_left if n.startswith("torso_")]
    assert len(torso) >= 4 and set(torso) <= set(two.free)
    k = system.index(torso)
    # nested data sets: the difference's variance is the smaller set's less the larger's
    spread = np.sqrt(np.maximum(one.std[k] ** 2 - two.std[k] ** 2, 0.0))
    assert (np.abs(one.params[k] - two.params[k]) < 4 * spread + 1e-12).all(), list(zip(
        torso, one.params[k] - two.params[k], spread, strict=True))
    assert (two.std[k] <= one.std[k] * (1 + 1e-9)).all()  # more data, no larger errors


def test_only_both_arms_separate_the_torso_from_the_right_arms_base():
    """With the left arm's base held (known by design), the left arm's rows determine the
    torso's pitch offset; the right arm's rows alone confound it with the right arm's base
    (a rotation of the torso is a rotation of that base): only the two together identify
    the right arm's base."""
    system = talos()
    held = [f"arm_left_1_joint.{c}" for c in ("x", "y", "z", "wx", "wy", "wz")]
    free = [n for n in system.calibratable if n not in held]
    data = simulate_system(system, 40, rng=1).data
    ana, _, section = analyse_system(system, [data], free)
    left, right = system.tips
    assert "torso_2_joint.offset" in ana.report.identifiable
    assert section["shared_seen_by"]["torso_2_joint.offset"] == [left]
    assert "torso_2_joint.offset" not in section["tips"][right]["identifiable"]
    only = set(section["combination_only"])
    assert only and all(n.startswith("arm_right_1_joint.") for n in only)
    # and with the right arm's rows alone the torso's offset is not identified at all
    alone = simulate_system(system, 40, tips=[right], rng=1).data
    ana_r, _, _ = analyse_system(system, [alone], free)
    assert "torso_2_joint.offset" not in ana_r.report.identifiable or not (
        {"arm_right_1_joint.x", "arm_right_1_joint.y"} <= set(ana_r.report.identifiable))


@pytest.mark.parametrize("kind", ["tracker", "point"])
def test_same_seed_same_result(kind):
    system = load_machine("rail-cell")
    a = simulate_system(system, 5, kind=kind, tips=["arm"], rng=3,
                        **({"carrier": "positioner", "centres": WORKPIECE[:2]}
                           if kind == "point" else {}))
    b = simulate_system(system, 5, kind=kind, tips=["arm"], rng=3,
                        **({"carrier": "positioner", "centres": WORKPIECE[:2]}
                           if kind == "point" else {}))
    np.testing.assert_array_equal(a.data.q, b.data.q)


GRIPPER = """<robot name="g">
  <link name="b"/><link name="l1"/><link name="l2"/><link name="fa"/><link name="fb"/>
  <joint name="j1" type="revolute"><origin xyz="0 0 0.3"/><parent link="b"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><origin xyz="0.3 0 0.1"/><parent link="l1"/>
    <child link="l2"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1"
    velocity="1"/></joint>
  <joint name="fa" type="prismatic"><origin xyz="0.2 0.01 0"/><parent link="l2"/>
    <child link="fa"/><axis xyz="0 1 0"/><limit lower="0" upper="0.05" effort="1"
    velocity="1"/></joint>
  <joint name="fb" type="prismatic"><origin xyz="0.2 -0.01 0"/><parent link="l2"/>
    <child link="fb"/><axis xyz="0 1 0"/><limit lower="-0.05" upper="0" effort="1"
    velocity="1"/><mimic joint="fa" multiplier="-1" offset="0.002"/></joint>
</robot>"""


def test_a_mimic_joints_multiplier_and_offset_are_identified(tmp_path):
    """A finger that follows the other (multiplier -1, offset 2 mm): its coupling is
    identified from tracker rows of both fingertips (noise-free: to round-off). The offset,
    like any prismatic joint's, moves the finger along its axis as its origin's translation
    does: the two are identified together (the origin absorbs it exactly)."""
    path = tmp_path / "g.urdf"
    path.write_text(GRIPPER)
    system = load_urdf_system(path, ["fa", "fb"])
    assert system.joint_names == ("j1", "j2", "fa")
    k = system.index(["fb.multiplier", "fb.offset"])
    np.testing.assert_allclose(system.nominal[k], [-1.0, 0.002])
    p = system.nominal
    tool = system.index(["fa.tool.x", "fb.tool.x", "fa.tool.z", "fb.tool.z"])
    p[tool] = [0.01, 0.01, 0.02, -0.02]  # targets off the fingers' axes
    system = system.with_params(p)

    def make(params):
        return [simulate_system(system, 40, true_params=params, rng=9).data]

    true, _, _ = truth(system, make, 10, length=2e-3, angle=2e-3)
    true[k] += [5e-4, 4e-4]  # the coupling off nominal
    data = make(true)[0]
    res = calibrate_system(system, data)
    assert "fb.multiplier" in res.free and "fb.offset" not in res.free
    assert res.identifiability.confounded_with["fb.offset"]  # with fb's origin
    m = system.index(["fb.multiplier"])[0]
    assert abs(res.params[m] - true[m]) < 1e-10
    assert res.errors_after.max() < 1e-12  # m
    # and the fingertips of the calibrated system at other rows
    val = simulate_system(system, 20, true_params=true, rng=11).data
    np.testing.assert_allclose(system.positions(val.q, res.params, val.marker), val.xyz,
                               atol=1e-12)
