"""One rule for "a calibration of the same arm" (`kinecal.kinematics.serial.same_arm`):
the calibration's ``implausible-change`` warning and the refusals of ``fk --params``,
``export``, ``compensate`` and `kinecal.load_result` agree, for every bundled arm and every
measurement kind; the 3-joint arm of plane touches that wandered off is warned and, with a
prior, stays a calibration of the same arm."""

import json
import warnings

import numpy as np
import pytest

import kinecal
from kinecal.calibration.blocks.simulate import simulate_kind
from kinecal.calibration.serial.simulate import random_configurations, random_errors, simulate
from kinecal.cli import main
from kinecal.errors import InputError
from kinecal.io.models import bundled_models

KINDS = ("tracker", "ballbar", "pair", "point", "plane")
ROWS = {"tracker": 30, "ballbar": 16, "pair": 40, "point": 10, "plane": 15}


def _other_arm(m):
    """The nominal arm with the twist of its second joint 40 deg off: another arm (its
    tool frames turn by more than a calibration can) that reaches the same workspace."""
    p = m.nominal
    p[m.index(["alpha2"])[0]] += np.radians(40.0)
    return p


def _calibrate(m, kind, truth, seed):
    if kind == "tracker":
        data = simulate(m, ROWS[kind], errors=truth - m.nominal, noise=0.05, rng=seed).data
    else:  # gauges placed for the nominal arm: the other one may miss a few (next seed)
        for k in range(3):
            try:
                data = [simulate_kind(m, kind, ROWS[kind], true_params=truth, noise=0.02,
                                      rng=seed + k).data]
                break
            except InputError:
                assert k < 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return kinecal.calibrate(m, data)


def _refusals(name, res, tmp_path) -> dict[str, bool]:
    """Whether each reader of results refuses `res` (as another arm)."""
    path = tmp_path / "r.json"
    res.to_json(path)
    q = random_configurations(res.nominal_model, 3, np.random.default_rng(0))
    joints = tmp_path / "q.csv"
    deg = np.degrees(q) if res.nominal_model.angle_unit == "deg" else q
    joints.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(map(str, r)) for r in deg))
    out = {"fk": main(["fk", name, str(joints), "--params", str(path)]) == 2,
           "export": main(["export", str(path), "--out", str(tmp_path / "m.yaml")]) == 2}
    try:
        kinecal.load_result(path)
        out["load_result"] = False
    except InputError:
        out["load_result"] = True
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kinecal.compensate(res, joints=q)
        out["compensate"] = False
    except InputError as exc:
        assert "same arm" in exc.message, exc.message
        out["compensate"] = True
    return out


ARMS = bundled_models()
#: every arm with every kind, the truth within the tolerances or another arm in turn, so
#: that each arm and each kind meets both
CASES = [(name, kind, (i + j) % 2 == 1) for i, name in enumerate(ARMS)
         for j, kind in enumerate(KINDS)]


@pytest.mark.parametrize("name, kind, other", CASES)
def test_warned_exactly_when_refused_later(name, kind, other, tmp_path, capsys):
    """Warned at calibration time exactly when every reader refuses the result later,
    never one without the other: a truth of another arm is always warned (every kind sees
    it), a tracker calibration within the tolerances never (a few gauge touches can let
    even that wander off: then both)."""
    m = kinecal.load_model(name)
    truth = _other_arm(m) if other else m.nominal + random_errors(m, np.random.default_rng(3))
    res = _calibrate(m, kind, truth, 5)
    warned = "implausible-change" in [w.code for w in res.warnings]
    refused = _refusals(name, res, tmp_path)
    capsys.readouterr()
    assert set(refused.values()) == {warned}, (warned, refused)
    if other:
        assert warned
    elif kind == "tracker":
        assert not warned


def test_plane_touches_of_a_three_joint_arm(tmp_path):
    """30 plane touches of a 3-joint arm: the plain fit turns alpha2 by 19 deg and the
    tool frames by 22 deg (refused later): warned, with what to do; a prior keeps it the
    same arm."""
    (tmp_path / "arm3.yaml").write_text(
        "name: arm3\nconvention: dh\nlength_unit: mm\nangle_unit: deg\njoints:\n"
        "  - {theta: 0, d: 300, a: 50, alpha: -90}\n  - {theta: -90, d: 0, a: 350, alpha: 0}\n"
        "  - {theta: 0, d: 0, a: 300, alpha: 0}\ntool: [50, 0, 0]\n"
        "joint_limits: [[-170, 170], [-100, 100], [-120, 120]]\n"
        "tolerances: {length: 0.5, angle: 0.1}\n")
    arm = str(tmp_path / "arm3.yaml")
    planes = str(tmp_path / "planes.csv")
    assert main(["simulate", arm, "--kind", "plane", "--plane", "400,0,300,1,0,0", "--plane",
                 "300,0,100,0,0,1", "--poses", "15", "--noise", "2", "--seed", "1",
                 "--out", planes]) == 0
    m = kinecal.load_model(arm)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = kinecal.calibrate(m, [planes])
        prior = kinecal.calibrate(m, [planes], prior="lengths=0.5,angles=0.1")
    found = [w for w in plain.warnings if w.code == "implausible-change"]
    assert found and "--prior" in found[0].message and "alpha2" in found[0].message
    assert "known fixture coordinates" in found[0].message
    assert "implausible-change" not in [w.code for w in prior.warnings]
    prior.to_json(tmp_path / "r.json")
    assert main(["fk", arm, planes, "--params", str(tmp_path / "r.json")]) == 0


def test_load_result_refuses_another_arm(tmp_path):
    """load_result ran no same-arm check: a result whose values make another arm (a link
    0.5 m longer) loaded silently in Python, where fk --params refused it."""
    m = kinecal.load_model("ur5")
    res = kinecal.calibrate(m, simulate(m, 30, noise=0.01, rng=1).data)
    path = tmp_path / "r.json"
    res.to_json(path)
    assert kinecal.load_result(path).params.shape == (m.n_params,)
    data = json.loads(path.read_text())
    data["parameters"]["a2"]["identified"] += 500.0
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match="not a calibration of the same arm") as err:
        kinecal.load_result(path)
    assert err.value.file == str(path)
    loaded = kinecal.load_result(path, check=False)  # still readable, to inspect it
    k = m.index(["a2"])[0]
    assert loaded.params[k] == pytest.approx(res.params[k] + 500.0)
