"""``kinecal compensate`` streams a long program block by block: the same rows as one call
of the API, warnings counted over the whole program, and memory that grows by a few numbers
per row (the rows' text and poses are never all held)."""

from __future__ import annotations

import csv
import json
import tracemalloc

import numpy as np
import pytest

import kinecal.compensation.api as api
from kinecal.calibration.serial.simulate import random_configurations
from kinecal.cli import main
from kinecal.io.models import load_model


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    d = tmp_path_factory.mktemp("stream")
    assert main(["simulate", "ur5", "--poses", "60", "--noise", "0.01", "--seed", "1",
                 "--out", str(d / "meas.csv")]) == 0
    assert main(["calibrate", "ur5", str(d / "meas.csv"), "--model-out",
                 str(d / "ur5-cal.yaml"), "--quiet"]) == 0
    return d / "ur5-cal.yaml"


def _program(path, n, seed=3):
    q = np.degrees(random_configurations(load_model("ur5"), n, np.random.default_rng(seed))
                   * 0.7)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["label", "q1", "q2", "q3", "q4", "q5", "q6"])
        w.writerows([f"P{k}", *r] for k, r in enumerate(q))
    return q


def test_blocks_give_the_rows_of_one_call_and_whole_program_warnings(calibrated, tmp_path,
                                                                     monkeypatch, capsys):
    q = _program(tmp_path / "prog.csv", 230)
    q[[40, 170]] = [[0, 0, 0, 0, 0, 400.0], [0, 0, 0, 0, 0, -400.0]]  # outside the limits
    with open(tmp_path / "prog.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["label", "q1", "q2", "q3", "q4", "q5", "q6"])
        w.writerows([f"P{k}", *r] for k, r in enumerate(q))
    monkeypatch.setattr(api, "BLOCK", 100)  # three blocks: 100, 100, 30 rows
    out = tmp_path / "out.csv"
    assert main(["compensate", str(calibrated), str(tmp_path / "prog.csv"), "--out", str(out),
                 "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    outside = [w for w in stats["warnings"] if w["code"] == "joints-outside-limits"]
    assert len(outside) == 1 and "2 row(s)" in outside[0]["message"] \
        and "first: row 41" in outside[0]["message"]
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["label"] for r in rows] == [f"P{k}" for k in range(230)]
    got = np.array([[float(r[f"q{j}"]) for j in range(1, 7)] for r in rows])
    model = load_model("ur5")
    scale = model.joint_scale()  # the file's degrees, as the command converts them
    res = api.compensate(load_model(str(calibrated)), model, joints=q * scale,
                         diagnose=False)
    np.testing.assert_array_equal(got, res.q / scale)
    assert stats["rows"] == 230 and stats["converged"] == int(res.converged.sum())
    assert stats["correction"] == res.stats()["correction"]


def test_memory_grows_by_a_few_numbers_per_row(calibrated, tmp_path, monkeypatch):
    monkeypatch.setattr(api, "BLOCK", 100)
    peaks = {}
    _program(tmp_path / "warm.csv", 120)
    main(["compensate", str(calibrated), str(tmp_path / "warm.csv"), "--out",
          str(tmp_path / "warm-out.csv"), "--quiet"])  # imports and caches first
    for n in (200, 800):
        _program(tmp_path / f"p{n}.csv", n)
        tracemalloc.start()
        assert main(["compensate", str(calibrated), str(tmp_path / f"p{n}.csv"), "--out",
                     str(tmp_path / f"o{n}.csv"), "--quiet"]) == 0
        peaks[n] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    per_row = (peaks[800] - peaks[200]) / 600
    # ProgramRows keeps ~170 bytes per row; held whole, the rows' text and 4x4 poses took
    # well over a kilobyte per row
    assert per_row < 400, per_row
