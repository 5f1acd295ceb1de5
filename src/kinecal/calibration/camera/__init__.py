"""Calibrate a serial arm from camera images: arm, camera mount and board in one bundle
adjustment (docs/arm-from-images.md).

The camera pixels are one residual block of the stacked calibration of several measurement
kinds (`kinecal.calibration.blocks`, docs/measurement-kinds.md): `CameraBlock`
(`kinecal.calibration.camera.residual_block`) mixes with tracker points, ballbars, sockets
and planes in one problem.

The measurement is the pixel position of every board corner seen by a camera on the
flange (eye-in-hand) or fixed beside the arm (eye-to-hand). The residual block
(`kinecal.calibration.camera.block.PixelBlock`) predicts every corner through the arm's
forward kinematics, the camera mount X, the board pose and the camera model, with the
analytic Jacobian with respect to the arm's parameters (chain rule through the serial
model's identification Jacobian of the flange pose) and to its own nuisance parameters
(X, board pose, intrinsics). The cost is the reprojection error of hand-eye calibration
from images (Tabb & Ahmad Yousef 2017; Koide & Menegatti 2019) with the arm's geometry
free, as in ROS robot_calibration's ``chain3d_to_camera2d`` and industrial_calibration's
``KinematicCalibrationProblem2D3D``.

Entry points:

- `calibrate_arm_camera` (`kinecal.calibration.camera.solve`): the bundle adjustment from
  joints and detected corners (the stacked calibration on one camera block), started by
  `closed_form_start`
  (`kinecal.calibration.camera.start`: nominal flange poses, per-image board poses,
  ``AX = XB`` / ``AX = ZB``);
- `camera_identifiability` (`kinecal.calibration.camera.identify`): what the pixels
  identify, in words (the base frame against the board pose, the flange against X, the
  scale set by the board's size);
- `ArmCameraResult` (`kinecal.calibration.camera.result`).

The images are read and the board detected by `kinecal.vision.arm_images`; stations of a
perturbed arm are rendered by `kinecal.vision.stations`.

Camera rigs (docs/rigs.md): several cameras and boards, each on a link of an arm or a
robot system (`kinecal.calibration.camera.rig_frames`), their corner pixels one residual
block (`RigBlock`, `kinecal.calibration.camera.rig_block`; the model and Jacobian in
`rig_pixels` and `rig_jacobian`, block-sparse normal equations), started without a guess
by a closed form per camera-board pair (`rig_start`); `calibrate_rig`
(`kinecal.calibration.camera.rig_solve`) with the mounts' covariance, camera-to-camera
extrinsics and what each mount takes up (`rig_identify`); `calibrate_rig_handeye`
(`rig_handeye`): several cameras' hand-eye from given robot poses.
"""

from kinecal._lazy import lazy_exports

__all__ = ["ArmCameraResult", "CameraBlock", "PixelBlock", "RigBlock", "Stations",
           "calibrate_arm_camera", "calibrate_rig", "calibrate_rig_handeye",
           "camera_identifiability", "closed_form_start"]

__getattr__, __dir__ = lazy_exports(__name__, {
    "ArmCameraResult": "kinecal.calibration.camera.result",
    "CameraBlock": "kinecal.calibration.camera.residual_block",
    "PixelBlock": "kinecal.calibration.camera.block",
    "RigBlock": "kinecal.calibration.camera.rig_block",
    "calibrate_rig": "kinecal.calibration.camera.rig_solve",
    "calibrate_rig_handeye": "kinecal.calibration.camera.rig_handeye",
    "Stations": "kinecal.calibration.camera.result",
    "calibrate_arm_camera": "kinecal.calibration.camera.solve",
    "camera_identifiability": "kinecal.calibration.camera.identify",
    "closed_form_start": "kinecal.calibration.camera.start",
})
