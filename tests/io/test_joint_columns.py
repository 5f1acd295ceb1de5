"""Joint columns named by the model's (URDF) joint names instead of q1..qn: measurement,
joint and program CSVs (kinecal.io.measurements.joint_columns)."""

from __future__ import annotations

import csv
from importlib import resources

import numpy as np
import pytest

from kinecal.calibration.serial.simulate import random_configurations, simulate
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.measurements import (
    joint_names,
    read_joints,
    read_measurements,
    write_measurements,
)
from kinecal.io.models import load_model
from kinecal.io.urdf import load_urdf
from kinecal.io.urdf_export import save_urdf

RTB = resources.files("rtbdata") / "xacro"
KR16 = RTB / "kuka_description/kuka_kr16/urdf/kr16_2.urdf"
IRB140 = RTB / "abb_irb140_description/urdf/irb140.urdf"


@pytest.fixture(scope="module")
def kr16():
    return load_urdf(KR16)


def rename(src, dst, mapping, order=None):
    """Copy CSV `src` to `dst` with header cells renamed (and columns reordered)."""
    with open(src, newline="") as fh:
        rows = list(csv.reader(fh))
    header = [mapping.get(c, c) for c in rows[0]]
    perm = list(range(len(header))) if order is None else [header.index(c) for c in order]
    with open(dst, "w", newline="") as fh:
        csv.writer(fh).writerows([[r[k] for k in perm] for r in [header, *rows[1:]]])
    return dst


def test_measurements_by_joint_names_read_as_q_columns(kr16, tmp_path):
    names = joint_names(kr16)
    assert names == tuple(f"joint_a{i}" for i in range(1, 7))
    sim = simulate(kr16, 15, errors="random", noise=1e-5, rng=0)
    qfile = tmp_path / "q.csv"
    write_measurements(qfile, sim.data, kr16)
    to_names = {f"q{i + 1}": n for i, n in enumerate(names)}
    # any column order: the joints are taken by name
    named = rename(qfile, tmp_path / "named.csv", to_names,
                   ["x", "y", "z", *reversed(names)])
    a, b = read_measurements(qfile, kr16), read_measurements(named, kr16)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.xyz, b.xyz)
    np.testing.assert_allclose(b.q, sim.data.q, atol=1e-12)
    np.testing.assert_array_equal(read_joints(named, kr16), a.q)
    # a joint program with joint_1..joint_6 (ABB's URDF names) is not the UR5 tracker export
    irb = load_urdf(IRB140)
    q = random_configurations(irb, 5, np.random.default_rng(1))
    prog = tmp_path / "irb.csv"
    with open(prog, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["label", *joint_names(irb)])
        w.writerows([[f"P{k}", *np.degrees(r)] for k, r in enumerate(q)])
    np.testing.assert_allclose(read_joints(prog, irb), q, atol=1e-12)


@pytest.mark.parametrize("header, match", [
    (["q1", "q2", "q3", "q4", "q5", "joint_a6", "x", "y", "z"], "mix q1..q6 and the model's"),
    (["joint_a1", "joint_a2", "joint_a3", "joint_a4", "joint_a5", "x", "y", "z"],
     "joint_a6 missing"),
    (["x", "y", "z"], "no joint columns: expected q1..q6 or model 'kuka_kr16_2'"),
    (["q1", "q2", "x", "y", "z"], r"2 joint columns \(q1, q2\).*expected q1..q6 or joint_a1"),
])
def test_mixed_partial_or_missing_joint_columns_are_refused(kr16, tmp_path, header, match):
    path = tmp_path / "bad.csv"
    path.write_text(",".join(header) + "\n" + ",".join(["1"] * len(header)) + "\n")
    with pytest.raises(InputError, match=match) as info:
        read_measurements(path, kr16)
    assert "bad.csv" in str(info.value)


def test_models_without_joint_names_keep_q_columns(tmp_path):
    ur5 = load_model("ur5")
    assert joint_names(ur5) == ()
    path = tmp_path / "m.csv"
    path.write_text("joint_a1,joint_a2,joint_a3,joint_a4,joint_a5,joint_a6,x,y,z\n"
                    + ",".join(["1"] * 9) + "\n")
    with pytest.raises(InputError, match="missing column"):
        read_measurements(path, ur5)


def test_compensate_program_by_joint_names(kr16, tmp_path, capsys):
    """The same program as q1..q6 and by joint names: the same compensated joints, written
    back into the program's own columns."""
    nominal = tmp_path / "kr16.urdf"
    save_urdf(kr16, nominal)
    p = kr16.nominal + np.where(kr16.is_angle(), 2e-4, 3e-4) * np.random.default_rng(5).normal(
        size=kr16.n_params)
    calibrated = tmp_path / "kr16-cal.urdf"
    save_urdf(kr16, calibrated, p)
    q = np.degrees(random_configurations(kr16, 6, np.random.default_rng(6)) * 0.7)
    names = joint_names(kr16)
    qprog, nprog = tmp_path / "q.csv", tmp_path / "n.csv"
    for path, cols in ((qprog, [f"q{i}" for i in range(1, 7)]), (nprog, list(names))):
        with open(path, "w", newline="") as fh:
            csv.writer(fh).writerows([["label", *cols], *[[f"P{k}", *r] for k, r in
                                                          enumerate(q)]])
    outs = []
    for path in (qprog, nprog):
        out = path.with_name(path.stem + "-out.csv")
        assert main(["compensate", str(calibrated), str(path), "--nominal", str(nominal),
                     "--out", str(out), "--quiet"]) == 0
        with open(out, newline="") as fh:
            outs.append(list(csv.DictReader(fh)))
    a, b = outs
    assert list(b[0])[:7] == ["label", *names] and f"d{names[0]}" in b[0]
    for ra, rb in zip(a, b, strict=True):
        assert [ra[f"q{i}"] for i in range(1, 7)] == [rb[n] for n in names]
        assert ra["correction"] == rb["correction"] and float(ra["correction"]) > 1e-5
