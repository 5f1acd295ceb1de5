"""Leg readings at the ends of a nominal leg range: a reading within 1 % of the stroke
outside it (reading noise; `kinecal stewart simulate` writes such rows near the range's
ends) is solved as read with one ``leg-range`` warning, in the API and the command line;
further out it is refused with its row."""

from __future__ import annotations

import numpy as np
import pytest

from kinecal.cli import main
from kinecal.diagnostics import KinecalWarning
from kinecal.errors import InputError
from kinecal.io.geometry import load_geometry


@pytest.fixture(scope="module")
def cmm():
    return load_geometry("liu2008-cmm")


def _legs(cmm, below: float, rows: int = 5, outside: tuple[int, ...] = (3,)) -> np.ndarray:
    """Neutral-pose readings with leg 1 of the rows `outside` at ``l_min - below``."""
    L = np.tile(cmm.inverse(cmm.neutral_pose()[None])[0], (rows, 1))
    L[list(outside), 0] = cmm.leg_range[0] - below
    return L


def test_reading_just_outside_is_solved_as_read_with_a_warning(cmm):
    L = _legs(cmm, 2e-6)
    with pytest.warns(KinecalWarning, match=r"1 of 5 rows read legs outside .*leg-range"):
        res = cmm.forward(L)
    assert res.converged.all()
    np.testing.assert_allclose(cmm.inverse(res.poses), L, atol=1e-12)


def test_reading_beyond_the_slack_is_refused_with_its_row(cmm):
    stroke = cmm.leg_range[1] - cmm.leg_range[0]
    with pytest.raises(InputError, match=r"row 4.*by more than 1% of the stroke"):
        cmm.forward(_legs(cmm, 0.011 * stroke))


def _write(path, L):
    path.write_text("l1,l2,l3,l4,l5,l6\n" + "".join(
        ",".join(repr(float(v)) for v in row) + "\n" for row in L))


def test_cli_warns_once_over_every_block_and_strict_refuses(cmm, tmp_path, capsys,
                                                            monkeypatch):
    import kinecal.cli._stewart_fk as cli_stewart

    monkeypatch.setattr(cli_stewart, "FK_BLOCK", 2)  # 3 blocks, two of them with a row outside
    legs = tmp_path / "legs.csv"
    _write(legs, _legs(cmm, 1e-6, rows=6, outside=(1, 4)))
    assert main(["stewart", "fk", "liu2008-cmm", str(legs)]) == 0
    out, err = capsys.readouterr()
    assert len(out.splitlines()) == 7 and out.count("true") == 6
    assert err.count("[leg-range]") == 1 and "2 of 6 rows" in err, err
    assert main(["stewart", "fk", "liu2008-cmm", str(legs), "--json"]) == 0
    out, err = capsys.readouterr()
    assert '"code": "leg-range"' in out and err.count("[leg-range]") == 1
    assert main(["stewart", "fk", "liu2008-cmm", str(legs), "--strict"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "leg-range" in err and err.startswith("kinecal: error:")
