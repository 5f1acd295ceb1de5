"""``kinecal reproduce liu2008 --quick``: papers/004 Table 3 beside kinecal's numbers."""

from __future__ import annotations

import json

import numpy as np

from kinecal.cli import main
from kinecal.experiments import liu2008


def test_reproduce_liu2008_quick(tmp_path):
    res = liu2008.run(quick=True, seed=0, out_dir=tmp_path)
    assert res["paper"] == "liu2008" and len(res["rows"]) == 6
    for row in res["rows"]:  # every printed digit of Table 3
        assert abs(row["newton_minus_paper"]) <= 5e-7
    assert res["pso"]["success"] >= res["pso"]["seeds"] - 1
    assert res["modes"]["total"] == 16 and res["modes"]["above_base"] == 8
    assert res["round_trip"]["max_position_error_m"] < 1e-9
    assert res["calibration"]["rank"] == 42
    assert res["calibration"]["leg_prediction_rms_m"] <= 1e-6
    assert (tmp_path / "liu2008_pso.png").stat().st_size > 1000
    text = liu2008.render(res)
    assert "0.925235" in text and "16 real" in text
    json.dumps(res)  # JSON-able
    # same seed, same numbers
    again = liu2008.run(quick=True, seed=0)
    assert again["rows"] == res["rows"]
    np.testing.assert_equal(again["pso"]["success"], res["pso"]["success"])


def test_reproduce_cli_json(capsys):
    assert main(["reproduce", "liu2008", "--quick", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["modes"]["above_base"] == 8
