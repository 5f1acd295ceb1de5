"""Kinematics: the machines' geometry, by machine kind.

- `kinecal.kinematics.serial`: serial arms (`SerialModel`: D-H, Craig, Hayati and URDF chains,
  batch forward kinematics, the analytic identification Jacobian, non-geometric joint errors,
  inverse kinematics). Papers 000 (D-H) and 002 (Hayati).
- `kinecal.kinematics.stewart`: the Stewart-platform CMM of paper 004 (`StewartPlatform`:
  inverse kinematics, forward kinematics by Newton, PSO and every assembly mode).

Nothing here knows about measurements or calibration; `kinecal.calibration` builds on it.
"""
