"""`--error-model auto`: coefficients without any effect are reported as such."""

import dataclasses

import numpy as np

from kinecal.calibration.serial.error_model import calibrate_error_model
from kinecal.calibration.serial.simulate import simulate
from kinecal.io.models import load_model
from kinecal.kinematics.serial.joint_errors import joint_errors_for


def test_auto_reports_coefficients_without_effect_as_no_effect():
    """PUMA 560 joint 1 is vertical: gravity never loads it. Through the cross-validation
    path (Gram matrix of every fold) its compliance columns are exact zeros and must stay
    "no effect", not "confounded with 1e-16 theta1"."""
    arm = load_model("puma560")
    model = dataclasses.replace(arm, joint_errors=joint_errors_for(arm, ("compliance",), 1))
    e = np.zeros(model.n_params)
    e[model.index(["dq2.compliance.tool", "dq3.compliance.tool"])] = [4e-4, -3e-4]
    sim = simulate(model, 80, errors=e, noise=0.005, rng=3)
    res = calibrate_error_model(arm, sim.data, "auto", folds=5)
    assert "compliance" in res.extra["error_model"]["selected"]
    je = res.extra["joint_errors"]
    dq1 = [n for n in je["unidentifiable"] if n.startswith("dq1.compliance")]
    assert len(dq1) == 7
    assert all(je["confounded_with"][n] == {} for n in dq1), \
        {n: je["confounded_with"][n] for n in dq1}
    text = res.summary()
    assert "dq1.compliance.tool: no effect on these poses" in text
    assert "confounded with no effect" not in text
