"""A tool that does not move at the nominal geometry (on the axis of a one-joint chain, as
a drone rotor's tip in example-robot-data's iris.urdf): the angle scale of the
identifiability analysis is the tool's distance from the base, not the round-off spread of
its points (1e-16 m made every angle weigh 1e16 times a length: all translations were
judged without effect and noise-free data were left 0.35 mm off, with no warning)."""

import numpy as np

from kinecal import calibrate
from kinecal.calibration.serial.problem import characteristic_length
from kinecal.calibration.serial.simulate import simulate
from kinecal.io.urdf import load_urdf

ROTOR = """<robot name="rotor">
  <link name="body"/>
  <link name="rotor"/>
  <joint name="spin" type="continuous">
    <parent link="body"/><child link="rotor"/>
    <origin xyz="0.13 -0.22 0.023" rpy="0 0 0"/><axis xyz="0 0 1"/>
  </joint>
</robot>
"""


def test_still_tool_round_trips_noise_free(tmp_path):
    path = tmp_path / "rotor.urdf"
    path.write_text(ROTOR)
    model = load_urdf(path)
    cal = simulate(model, 60, errors="random", rng=1)
    val = simulate(model, 30, errors=cal.true_params - model.nominal, rng=2)
    # every nominal tool point is the same point: the spread is round-off
    L = characteristic_length(model, cal.data)
    assert np.isclose(L, np.linalg.norm([0.13, -0.22, 0.023]), rtol=1e-12)
    res = calibrate(model, cal.data, "lm", validate=val.data)
    assert {"base.x", "base.y", "tool.x", "tool.y"} <= set(res.identifiability.identifiable)
    assert np.abs(res.errors_before).max() > 1e-4  # the errors move the tool by ~1 mm
    assert np.abs(res.val_after).max() < 1e-12
