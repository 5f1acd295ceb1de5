"""Observability-optimal pose selection."""

import numpy as np

import kinecal
from kinecal.calibration.identifiability import observability_indices
from kinecal.calibration.serial.pose_selection import _blocks, select_poses
from kinecal.calibration.serial.problem import resolve_free
from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.cli import main


def test_selected_poses_beat_random_ones():
    m = kinecal.load_model("irb120")
    cand = random_configurations(m, 1500, np.random.default_rng(0))
    ident, _ = resolve_free(m, simulate(m, 50, errors="zero", rng=1).data, "identifiable")
    idx, obs = select_poses(m, cand, 15, free=ident)
    assert len(set(idx.tolist())) == 15
    B = _blocks(m, cand, ident)
    rng = np.random.default_rng(2)
    o1_random = [observability_indices(np.linalg.svd(
        B[rng.choice(1500, 15, replace=False)].reshape(-1, len(ident)), compute_uv=False),
        45)["O1"] for _ in range(20)]
    assert obs["O1"] > max(o1_random)
    # and the calibration from them validates better than from random poses
    opt, rand = [], []
    for seed in range(4):
        e = np.zeros(m.n_params)
        ii = m.index(ident)
        e[ii] = np.random.default_rng(seed).uniform(-1, 1, ii.size) * np.where(
            m.is_angle()[ii], 0.002, 0.1)
        val = simulate(m, 200, errors=e, rng=100 + seed)
        for sel, store in ((idx, opt), (rng.choice(1500, 15, replace=False), rand)):
            sim = simulate(m, 0, errors=e, noise=0.02, q=cand[sel], rng=seed)
            res = kinecal.calibrate(m, sim.data, free=ident, validate=val.data)
            store.append(res.validation_stats["after"]["mean"])
    assert np.mean(opt) < np.mean(rand)


def test_cli_select_poses(tmp_path):
    out = tmp_path / "q.csv"
    assert main(["select-poses", "irb120", "--count", "12", "--candidates", "300",
                 "--out", str(out)]) == 0
    q = np.loadtxt(out, delimiter=",", skiprows=1)
    assert q.shape == (12, 6)
    assert main(["select-poses", "irb120", "--count", "3", "--out", str(out)]) == 2


def test_markers_every_marker_is_measured_and_observable(tmp_path, capsys):
    """A model with three markers: each candidate is one configuration measured at every
    marker (as simulate does), so every marker's tool point is identifiable and the
    selection maximises the information of all of them."""
    from kinecal.calibration.serial.pose_selection import candidate_measurements, marker_rows
    from kinecal.io.models import save_model

    points = {"A": [0.0, 0.0, 31.0], "B": [52.0, -3.0, 20.0], "C": [-4.0, 61.0, 25.0]}
    m = kinecal.load_model("ur5").with_markers(points)
    cand = random_configurations(m, 400, np.random.default_rng(0))
    data = candidate_measurements(m, cand)
    assert len(data) == 1200 and data.marker.tolist()[:4] == [0, 1, 2, 0]
    ident, _ = resolve_free(m, data, "identifiable")
    # (tool.B.z: d6 + tool.A.z - tool.C.z, the list-last rule)
    assert {f"tool.{k}.{c}" for k in "BC" for c in "xy"} <= set(ident) and len(ident) == 31
    idx, obs = select_poses(m, cand, 8, free=ident)  # 8 x 9 = 72 equations
    # the selection sees every marker: its information matrix has full rank on ident
    rows, marker = marker_rows(m, cand[idx])
    J = m.identification_jacobian(rows, marker=marker)[:, :, m.index(ident)].reshape(
        -1, len(ident))
    s = np.linalg.svd(J / np.linalg.norm(J, axis=0), compute_uv=False)
    assert s[-1] > 1e-3 * s[0]
    # and is at least as informative as configurations chosen for the first marker only
    # (the former behaviour), which also refused 4 configurations: 12 rows for 31 unknowns
    first = kinecal.load_model("ur5").with_markers({"A": points["A"]})
    ident_first, _ = resolve_free(first, candidate_measurements(first, cand), "identifiable")
    idx_first, _ = select_poses(first, cand, 8, free=ident_first)
    B = _blocks(m, cand, ident)
    o1 = observability_indices(np.linalg.svd(B[idx_first].reshape(-1, len(ident)),
                                             compute_uv=False), 72)["O1"]
    assert obs["O1"] > o1
    idx4, _ = select_poses(m, cand, 4, free=ident)  # 36 equations
    assert len(set(idx4.tolist())) == 4
    # the command line plans with every marker as well
    path = tmp_path / "three.yaml"
    save_model(m, path)
    out = tmp_path / "q.csv"
    assert main(["select-poses", str(path), "--count", "8", "--candidates", "300",
                 "--out", str(out)]) == 0
    assert np.loadtxt(out, delimiter=",", skiprows=1).shape == (8, 6)
    assert f"({len(ident)} identifiable parameters)" in capsys.readouterr().err
