"""A small, real calibration result shared by the report tests (simulated UR5)."""

import pytest

import kinecal
from kinecal.calibration.serial.simulate import simulate
from kinecal.data import Measurements


@pytest.fixture(scope="session")
def ur5_result():
    """LM calibration of the UR5 on 60 simulated poses (random errors, 10 um noise),
    validated on 15 other poses of the same true arm."""
    model = kinecal.load_model("ur5")
    d = simulate(model, 75, errors="random", noise=0.01, rng=3).data
    cal = Measurements(d.q[:60], d.xyz[:60], source="simulated")
    val = Measurements(d.q[60:], d.xyz[60:], source="simulated")
    return kinecal.calibrate(model, cal, validate=val)
