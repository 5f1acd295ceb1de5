"""What each camera and board of a rig is confounded with, in words.

The stacked calibration (`kinecal.calibration.blocks`) decides which of the model's
parameters the pixels identify with every mount free, and holds the others at nominal.
This module says *which mount* takes each held parameter up: the parameter's pixel
Jacobian column is fitted by the mounts' columns and the identified parameters'
(`kinecal.calibration.camera.identify` does the same for one camera), and a mount that
carries a share of it is the one it is confounded with:

- a **static camera** (on ``world``) and the robot's base: anything that moves the whole
  arm rigidly (the base frame, the first joint's position and zero) is a move of every
  static camera and board the other way: only their relative poses are seen;
- a **mount on a flange or a tip** and the last link's offsets and the tool frame: they
  move the mounted camera or board as its mount does;
- a **camera's free intrinsics**, which take up what changes its image alone.

A robot system adds one: a head's base against its own camera (a pan-tilt unit whose base
the pixels place only through its camera).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.camera.identify import SHARE, _orth, _unit
from kinecal.calibration.camera.rig_frames import WORLD
from kinecal.calibration.camera.rig_pixels import RigPixels

Array = NDArray[np.float64]

__all__ = ["RigIdentifiability", "rig_identifiability"]


@dataclass
class RigIdentifiability:
    """Result of `rig_identifiability`.

    Attributes
    ----------
    taken_up_by : dict of str to list of str
        For each held parameter, the mounts (``camera NAME``, ``board NAME``, ``NAME
        intrinsics``) that imitate it.
    mounts : dict of str to list of str
        For each mount, the held parameters it takes up.
    scale_free : bool
        A uniform scale of the whole rig and model is imitated by the boards' sizes.
    sentences : list of str
    """

    taken_up_by: dict[str, list[str]] = field(default_factory=dict)
    mounts: dict[str, list[str]] = field(default_factory=dict)
    scale_free: bool = True
    sentences: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"taken_up_by": self.taken_up_by, "confounded": self.mounts,
                "scale_from_boards": self.scale_free, "not_seen": list(self.sentences)}


def rig_identifiability(pixels: RigPixels, model, params: Array, nu: Array,
                        identified: Sequence[str], held: Sequence[str],
                        tol: float = 1e-4, confounded: dict | None = None,
                        scale_known: bool = False) -> RigIdentifiability:
    """Which mount takes up each `held` parameter (module docstring).

    Parameters
    ----------
    pixels : RigPixels
    model : SerialModel or SystemModel
    params, nu : ndarray
        Where the analysis is made (the solution).
    identified, held : sequence of str
        The free and the held parameters of the calibration.
    tol : float
        Relative rank threshold of the scale test.
    confounded : dict, optional
        The calibration's ``confounded_with`` (held parameter -> the free parameters whose
        combination has its effect), for the words of the held parameters no mount takes.
    scale_known : bool
        Other measurements carry lengths (a tracker's, a ballbar's): the scale is theirs.
    """
    names = list(identified) + list(held)
    cols = model.index(names) if names else np.zeros(0, np.intp)
    _, J = pixels.predict(params, nu, cols, jac=True, strict=False)
    m = 2 * pixels.n_corners
    ok = np.isfinite(J.arm).all(axis=(1, 2))
    rows = np.repeat(ok, 2)
    Ja = J.arm.reshape(m, -1)[rows]
    Jn = J.dense_nuisance(pixels.n_nuisance)[rows]
    An, _ = _unit(Jn)
    Aa, _ = _unit(Ja)
    k = len(identified)
    basis = np.hstack([An, Aa[:, :k]])
    groups = pixels.nuisance_groups()
    out = RigIdentifiability()
    scale = np.abs(Ja).max(initial=0.0)
    none = []
    coefs = np.linalg.lstsq(basis, Aa[:, k:], rcond=None)[0] if held else None
    for j, name in enumerate(held):
        if np.abs(Ja[:, k + j]).max(initial=0.0) <= 1e-12 * max(scale, 1e-300):
            out.taken_up_by[name] = []
            none.append(name)
            continue
        coef = coefs[:, j]
        by = [g for g, sl in groups.items() if np.linalg.norm(An[:, sl] @ coef[sl]) > SHARE]
        out.taken_up_by[name] = by
        for g in by:
            out.mounts.setdefault(g, []).append(name)
    out.scale_free = not scale_known and _scale_free(pixels, params, nu, basis, rows, tol)
    out.sentences = _sentences(out, pixels, none, confounded or {})
    return out


def _scale_free(pixels: RigPixels, params: Array, nu: Array, basis: Array,
                rows: NDArray[np.bool_], tol: float) -> bool:
    """Whether a scale of every board (their corners ``P -> (1 + s) P``) is imitated by the
    free columns `basis` (of the residual `rows`), by central differences of the pixels."""
    P = pixels.P
    h = 1e-6
    try:
        pixels.P = P * (1 + h)
        up = pixels.predict(params, nu, strict=False)[0]
        pixels.P = P * (1 - h)
        down = pixels.predict(params, nu, strict=False)[0]
    finally:
        pixels.P = P
    s = np.nan_to_num(((up - down) / (2 * h)).ravel()[rows])
    if np.linalg.norm(s) == 0:
        return True
    Q = _orth(basis)
    u = s / np.linalg.norm(s)
    return bool(np.linalg.norm(u - Q @ (Q.T @ u)) < np.sqrt(tol))


def _sentences(info: RigIdentifiability, pixels: RigPixels, none: list[str],
               confounded: dict) -> list[str]:
    links = {f"camera {c.name}": c.link for c in pixels.cameras}
    links.update({f"board {b.name}": b.link for b in pixels.boards})
    out = []
    grouped: dict[tuple, list[str]] = {}
    for g, params in info.mounts.items():  # mounts that take up the same, said once
        grouped.setdefault((links.get(g) == WORLD, links.get(g) is None, tuple(params)),
                           []).append(g)
    for (static, intrinsics, params), names in grouped.items():
        where = ", ".join(f"{g} ({links.get(g) or 'intrinsics'})" for g in names)
        if static:
            what = ("a static mount and the robot's base are seen only together (a rigid "
                    "move of the whole robot is the mount's move the other way)")
        elif not intrinsics:
            what = "they move what hangs from the link as this mount does"
        else:
            what = "they change this camera's image as its intrinsics do"
        verb = "takes" if len(names) == 1 else "each take"
        out.append(f"{where} {verb} up {', '.join(params)}: {what}; held at nominal, the "
                   "mount is given in the frame they make")
    if none:
        out.append(f"{', '.join(none)}: no effect on any image (a tool point after the link a "
                   "camera or board hangs from); held at nominal")
    for n in [n for n, by in info.taken_up_by.items() if not by and n not in none]:
        parts = ", ".join(confounded.get(n, {})) or "other parameters"
        out.append(f"{n}: a combination of {parts} (these images cannot tell them apart); "
                   "held at nominal")
    if info.scale_free:
        out.append("scale: set by the boards' printed sizes alone: every identified length "
                   "scales with them (the images cannot check it)")
    return out
