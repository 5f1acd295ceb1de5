"""Assembly modes, PSO forward kinematics (papers/004 sec. 3) and geometry files."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal.errors import InputError
from kinecal.io.geometry import bundled_geometries, load_geometry, save_geometry
from kinecal.kinematics.stewart.platform import StewartPlatform, radians_to_degrees
from kinecal.spatial import matrix_from_rpy

TABLE3_LEGS = np.array([0.750, 0.780, 0.800, 0.900, 0.870, 0.850])
TABLE3_POSE_DEG = np.array([0.039860, 0.095930, 0.925235, -12.697325, 6.403095, 15.133206])


@pytest.fixture(scope="module")
def cmm() -> StewartPlatform:
    return StewartPlatform.liu2008()


@pytest.fixture(scope="module")
def modes(cmm):
    return cmm.forward_all(TABLE3_LEGS, rng=0)


def test_forward_all_finds_16_modes_8_above(cmm, modes):
    assert len(modes) == 16
    assert modes.above.sum() == 8
    assert modes.above[:8].all()  # sensible ordering: above the base first
    np.testing.assert_allclose(cmm.inverse(modes.poses), np.tile(TABLE3_LEGS, (16, 1)), atol=1e-11)
    # the first is the machine's actual pose (Table 3)
    np.testing.assert_allclose(radians_to_degrees(modes.poses[0]), TABLE3_POSE_DEG, atol=5e-7)
    # distinct solutions
    d = np.linalg.norm(modes.poses[:, None, :3] - modes.poses[None, :, :3], axis=-1)
    assert d[~np.eye(16, dtype=bool)].min() > 1e-4


def test_forward_all_below_modes_are_mirror_images(cmm, modes):
    M = np.diag([1.0, 1.0, -1.0])
    s = cmm.probe_vector
    R = matrix_from_rpy(modes.poses[:, 3:])
    centre = modes.poses[:, :3] - R @ s
    up, down = np.flatnonzero(modes.above), np.flatnonzero(~modes.above)
    mirrored = centre[up] @ M
    for c in mirrored:  # every mirrored centre is one of the modes below
        assert np.linalg.norm(centre[down] - c, axis=1).min() < 1e-9


def test_forward_all_same_seed_same_result(cmm):
    a = cmm.forward_all(TABLE3_LEGS, rng=5, starts=1024)
    b = cmm.forward_all(TABLE3_LEGS, rng=5, starts=1024)
    np.testing.assert_array_equal(a.poses, b.poses)


def test_forward_all_rejects_several_rows(cmm):
    with pytest.raises(InputError, match="one leg set"):
        cmm.forward_all(np.tile(TABLE3_LEGS, (2, 1)))


def test_pso_table3_30_seeds(cmm):
    exact = cmm.forward(TABLE3_LEGS).poses[0]
    hits, its = 0, []
    for seed in range(30):
        res = cmm.forward(TABLE3_LEGS, method="pso", rng=seed, on_failure="flag")
        hits += np.linalg.norm(res.poses[0, :3] - exact[:3]) <= 0.5e-6
        its.append(res.iterations[0])
    assert hits >= 29  # the paper's 0.5 um precision
    assert np.median(its) < 150  # paper: about 55 iterations


def test_pso_same_seed_bit_identical(cmm):
    a = cmm.forward(TABLE3_LEGS, method="pso", rng=3, on_failure="flag")
    b = cmm.forward(TABLE3_LEGS, method="pso", rng=3, on_failure="flag")
    np.testing.assert_array_equal(a.poses, b.poses)
    assert a.nfev[0] == 80 * (a.iterations[0] + 1)


def test_pso_unknown_setting(cmm):
    with pytest.raises(InputError, match="PSO settings"):
        cmm.forward(TABLE3_LEGS, method="pso", options={"particles": 10})


def test_bundled_geometry_is_table2(cmm):
    assert "liu2008-cmm" in bundled_geometries()
    g = load_geometry("liu2008-cmm")
    np.testing.assert_allclose(g.parameters, cmm.parameters, atol=1e-15)
    assert g.leg_range == (0.75, 0.97) and g.probe_offset == 0.18


def test_geometry_yaml_round_trip(cmm, tmp_path):
    g = cmm.with_parameters(cmm.parameters + np.linspace(-1e-3, 1e-3, 42))
    path = tmp_path / "cal.yaml"
    save_geometry(g, path)
    h = load_geometry(path)
    np.testing.assert_array_equal(h.parameters, g.parameters)
    assert h.leg_range == g.leg_range and h.probe_offset == g.probe_offset


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("kind: stewart\nleg_range: [0.7, 0.9]\nbase_radius: 0.5\n", "missing"),
        ("kind: stewart\nleg_range: [0.9, 0.7]\n", "leg_range"),
        ("leg_range: [0.7, 0.9]\nbase_joints: [[0,0,0]]\nplatform_joints: [[0,0,0]]\n", "6 points"),
        ("[1, 2", "YAML"),
        ("- 1\n- 2\n", "mapping"),
    ],
)
def test_bad_geometry_files(tmp_path, text, match):
    path = tmp_path / "g.yaml"
    path.write_text(text)
    with pytest.raises(InputError, match=match):
        load_geometry(path)


def test_unknown_geometry_name():
    with pytest.raises(InputError, match="unknown geometry"):
        load_geometry("no-such-machine")
