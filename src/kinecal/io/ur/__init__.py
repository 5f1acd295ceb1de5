"""Universal Robots files: the controller's factory calibration and the ROS driver's
kinematics file.

* `kinecal.io.ur.robots`: the nominal D-H tables of the UR arm types (``ur3`` ... ``ur30``)
  and `ur_model`, a kinecal model of one of them (optionally with factory deltas).
* `kinecal.io.ur.conf`: `read_calibration_conf`, the controller's ``calibration.conf``
  (``[mounting]`` ``delta_theta, delta_a, delta_d, delta_alpha``, radians and metres).
* `kinecal.io.ur.kinematics`: `ur_kinematics` / `save_ur_kinematics`, the
  ``default_kinematics.yaml`` that ur_description's xacro (and so ur_robot_driver and
  MoveIt) loads, exact for any UR-type D-H model.

No paper: the D-H convention is Hu, Xiao and Li (2005)'s eq. 1 (``docs/conventions.md``).
"""
