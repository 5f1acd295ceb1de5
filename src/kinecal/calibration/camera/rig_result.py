"""`RigResult`: the outcome of a rig calibration (`kinecal.calibration.camera.rig_solve`).

Its JSON is that of the stacked calibration (parameters, free, identifiability, the
measurement set's noise; a robot system's ``system`` and ``by_tip``) with the rig's:

- ``cameras[NAME] = {link, pose, sigma, intrinsics, images, rms_px}``: ``pose`` the 4x4
  camera pose in its link's frame (OpenCV camera axes: x right, y down, z along the view;
  the model's length unit), ``sigma`` its standard deviations (rotation in deg about the
  camera's axes, translation);
- ``boards[NAME] = {link, pose, sigma, spec}``: the board's frame in its link's;
- ``camera_to_camera[A][B] = {pose, sigma}``: camera B in camera A's frame, for cameras on
  one link (a stereo pair, static cameras), with the uncertainty the fit gives it (the
  two mounts' covariance propagated);
- ``rig``: which mount takes up which held parameter, in words
  (`kinecal.calibration.camera.rig_identify`);
- ``calibration`` / ``validation``: the reprojection RMS per image before (the model at
  nominal, the mounts fitted) and after, overall and per camera.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal._files import write_text_atomic
from kinecal.calibration.camera.rig_identify import RigIdentifiability
from kinecal.diagnostics import Diagnostic
from kinecal.spatial import axis_angle_from_matrix

Array = NDArray[np.float64]

__all__ = ["RigResult", "mount_entries", "pixel_stats"]


def _rms(v: Array) -> float:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v**2))) if v.size else float("nan")


def pixel_stats(rms: Array) -> dict[str, Any]:
    """``{n, rms_px, max_image_rms_px, median_image_rms_px}`` of per-image RMS values."""
    s = np.asarray(rms, float)
    return {"n": int(s.size), "rms_px": _rms(s),
            "max_image_rms_px": float(s.max()) if s.size else float("nan"),
            "median_image_rms_px": float(np.median(s)) if s.size else float("nan")}


def _by_camera(rms: Array, camera: Array, names: list[str]) -> dict[str, Any]:
    return {n: pixel_stats(np.asarray(rms)[np.asarray(camera) == c])
            for c, n in enumerate(names) if np.any(np.asarray(camera) == c)}


def mount_entries(res: Any) -> tuple[dict, dict, dict]:
    """The ``cameras``, ``boards`` and ``camera_to_camera`` JSON entries of a result with
    `RigResult`'s mount attributes (a rig calibration's, a rig hand-eye calibration's)."""
    cam_names = [c.name for c in res.cameras]
    cams = {}
    for c, m in enumerate(res.cameras):
        sel = np.asarray(res.camera_of) == c
        s = res.camera_sigma[c]
        intr = {"K": res.K[c].tolist(), "dist": res.dist[c].tolist(),
                "refined": bool(res.intrinsics_free[c])}
        if res.intrinsics_sigma[c] is not None:
            intr["sigma"] = np.asarray(res.intrinsics_sigma[c]).tolist()
        cams[m.name] = {"link": m.link, "pose": res.camera_poses[c].tolist(),
                        "sigma": {"rotation_deg": np.degrees(s[:3]).tolist(),
                                  "translation": s[3:].tolist()},
                        "intrinsics": intr, "images": int(sel.sum()),
                        "rms_px": _rms(res.after_px[sel])}
    boards = {}
    for b, m in enumerate(res.boards):
        s = res.board_sigma[b]
        boards[m.name] = {"link": m.link, "pose": res.board_poses[b].tolist(),
                          "sigma": {"rotation_deg": np.degrees(s[:3]).tolist(),
                                    "translation": s[3:].tolist()},
                          "spec": res.board_specs[b]}
    pairs: dict[str, dict] = {}
    for (a, b), (T, s) in res.pairs.items():
        pairs.setdefault(cam_names[a], {})[cam_names[b]] = {
            "pose": T.tolist(), "distance": float(np.linalg.norm(T[:3, 3])),
            "sigma": {"rotation_deg": np.degrees(s[:3]).tolist(),
                      "translation": s[3:].tolist()}}
    return cams, boards, pairs


@dataclass
class RigResult:
    """A rig calibration (module docstring).

    Attributes
    ----------
    fit : KindsCalibrationResult
        The stacked calibration (model, parameters, uncertainty, identifiability).
    cameras, boards : list of Mount
    camera_poses, board_poses : list of ndarray, shape (4, 4)
        Calibrated mounts (``cam2link``, ``board2link``).
    camera_sigma, board_sigma : list of ndarray, shape (6,)
        Standard deviations: rotation (rad, about the mount's own axes), translation.
    K, dist : list of ndarray
        Each camera's intrinsics (refined where free).
    intrinsics_free : list of bool
    intrinsics_sigma : list of ndarray or None
    pairs : dict
        ``{(a, b): (pose (4, 4), sigma (6,))}`` for cameras on one link.
    identifiability : RigIdentifiability
    names : list of str
    camera_of : ndarray of int
    before_px, after_px : ndarray, shape (n,)
    outliers : list of int
    sigma_px : float
    """

    fit: Any
    cameras: list
    boards: list
    board_specs: list[str]
    camera_poses: list[Array]
    board_poses: list[Array]
    camera_sigma: list[Array]
    board_sigma: list[Array]
    K: list[Array]
    dist: list[Array]
    intrinsics_free: list[bool]
    intrinsics_sigma: list[Array | None]
    pairs: dict
    identifiability: RigIdentifiability
    names: list[str]
    camera_of: Array
    before_px: Array
    after_px: Array
    outliers: list[int]
    sigma_px: float
    val_names: list[str] = field(default_factory=list)
    val_camera: Array | None = None
    val_before_px: Array | None = None
    val_after_px: Array | None = None
    seconds: float = 0.0
    warnings: list[Diagnostic] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)
    #: the mounts and intrinsics fitted with the model at nominal (the "before")
    start_mounts: tuple | None = None

    @property
    def model(self):
        """The calibrated model (held parameters at nominal)."""
        return self.fit.model

    @property
    def params(self) -> Array:
        return self.fit.params

    @property
    def free(self) -> list[str]:
        return list(self.fit.free)

    def camera(self, name: str) -> Array:
        """The calibrated pose ``(4, 4)`` of camera `name` in its link."""
        return self.camera_poses[[c.name for c in self.cameras].index(name)]

    def board(self, name: str) -> Array:
        """The calibrated pose ``(4, 4)`` of board `name` in its link."""
        return self.board_poses[[b.name for b in self.boards].index(name)]

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict[str, Any]:
        """JSON of ``kinecal calibrate MODEL STATIONS.csv --images DIR --camera ...
        --board ...`` (module docstring)."""
        from kinecal.calibration.serial.result import _finite

        out = self.fit.to_dict()
        out.pop("predicted_error", None)
        cams, boards, pairs = mount_entries(self)
        names = [c.name for c in self.cameras]
        keep = np.ones(len(self.names), bool)
        keep[self.outliers] = False
        out.update({
            "kind": "rig", "cameras": cams, "boards": boards, "camera_to_camera": pairs,
            "held": [n for n in self.fit.nominal_model.calibratable if n not in set(self.free)],
            "rig": self.identifiability.to_dict(),
            "not_seen": list(self.identifiability.sentences),
            "calibration": {"before": pixel_stats(self.before_px[keep]),
                            "after": pixel_stats(self.after_px[keep]),
                            "by_camera": {n: {"before": b, "after": a} for (n, b), a in zip(
                                _by_camera(self.before_px, self.camera_of, names).items(),
                                _by_camera(self.after_px, self.camera_of, names).values(),
                                strict=True)}},
            "validation": None, "sigma_px": self.sigma_px,
            "images": [{"image": n, "camera": names[int(c)],
                        "status": "outlier" if i in self.outliers else "used",
                        "rms_px_before": float(b), "rms_px_after": float(a)}
                       for i, (n, c, b, a) in enumerate(zip(self.names, self.camera_of,
                                                            self.before_px, self.after_px,
                                                            strict=True))],
            "outliers": [self.names[i] for i in self.outliers], "seconds": self.seconds,
        })
        if self.val_before_px is not None:
            out["validation"] = {
                "before": pixel_stats(self.val_before_px),
                "after": pixel_stats(self.val_after_px), "images": list(self.val_names),
                "by_camera": {n: {"before": b, "after": a} for (n, b), a in zip(
                    _by_camera(self.val_before_px, self.val_camera, names).items(),
                    _by_camera(self.val_after_px, self.val_camera, names).values(),
                    strict=True)}}
        out.update(self.extra)
        out["warnings"] = [d.to_dict() for d in self.warnings]
        return _finite(out)

    def to_json(self, path: str | Path) -> None:
        """Write `to_dict` as JSON (atomic)."""
        write_text_atomic(path, json.dumps(self.to_dict(), indent=2, default=float) + "\n")

    # ------------------------------------------------------------------ text
    def summary(self) -> str:
        """Plain-text summary: images, reprojection before and after, every mount with
        its uncertainty, camera-to-camera extrinsics, what the rig cannot see."""
        nom = self.fit.nominal_model
        unit = nom.length_unit
        keep = np.ones(len(self.names), bool)
        keep[self.outliers] = False
        rep = self.fit.identifiability
        lines = [f"model {nom.name}: {len(self.names)} images of {len(self.cameras)} camera(s) "
                 f"and {len(self.boards)} board(s) ({len(self.outliers)} outlier(s)); "
                 f"{len(self.free)} parameters free (rank {rep.rank} of {len(rep.names)} "
                 "beside the mounts)",
                 f"reprojection RMS: {_rms(self.before_px[keep]):.3f} px at nominal (mounts "
                 f"refined) -> {_rms(self.after_px[keep]):.3f} px calibrated (corner sigma "
                 f"{self.sigma_px:.3f} px)"]
        if self.val_before_px is not None:
            lines.append(f"validation ({len(self.val_before_px)} images): "
                         f"{_rms(self.val_before_px):.3f} px -> {_rms(self.val_after_px):.3f} "
                         "px")
        lines.append("mounts (pose in the link's frame; 1 sigma):")
        for what, mounts, poses, sig in (("camera", self.cameras, self.camera_poses,
                                          self.camera_sigma),
                                         ("board", self.boards, self.board_poses,
                                          self.board_sigma)):
            for m, T, s in zip(mounts, poses, sig, strict=True):
                t = ", ".join(f"{v:.3f}" for v in T[:3, 3])
                lines.append(f"  {what} {m.name} on {m.link}: t = ({t}) {unit} +- "
                             f"{np.linalg.norm(s[3:]):.3f} {unit}, rotation +- "
                             f"{np.degrees(np.linalg.norm(s[:3])):.4f} deg")
        names = [c.name for c in self.cameras]
        for (a, b), (T, s) in self.pairs.items():
            turn = np.degrees(np.linalg.norm(axis_angle_from_matrix(T[:3, :3])))
            lines.append(f"  camera {names[b]} in camera {names[a]}: baseline "
                         f"{np.linalg.norm(T[:3, 3]):.3f} {unit} +- "
                         f"{np.linalg.norm(s[3:]):.3f}, rotation {turn:.3f} deg +- "
                         f"{np.degrees(np.linalg.norm(s[:3])):.4f}")
        lines.append("what the rig cannot see (held at nominal):")
        lines += [f"  {s}" for s in self.identifiability.sentences]
        lines.append(f"{self.fit.iterations} iterations, {self.fit.evaluations} evaluations, "
                     f"{self.seconds:.3g} s")
        if self.outliers:
            lines.append("outlier images: " + ", ".join(self.names[i] for i in self.outliers))
        if self.warnings:
            lines += ["", f"warnings ({len(self.warnings)}):"]
            lines += [f"  [{d.code}] {d.message}" for d in self.warnings]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()
