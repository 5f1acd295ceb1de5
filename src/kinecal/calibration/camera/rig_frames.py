"""The links cameras and boards of a rig are mounted on, and their poses per image.

A camera or a board of a rig hangs from a *link*: ``world`` (the measurement frame: a
static camera, a board on a table), the arm's ``flange`` (its end frame), or any link of
a robot system (`kinecal.kinematics.tree.SystemModel`: a head link, another arm's tip, a
positioner's table; a tip's name stands for its link). `LinkFrames` gives every mounting
link's pose for each image's joint readings and, for the calibration, its pose Jacobian
with respect to the model's parameters (position, and the small rotation vector in the
world frame: ``dR = [dphi]x R``), from `SerialModel.sweep` or `SystemModel.link_sweep`.
`FixedFrames` is the same interface over link poses given per image (the flange poses of
a hand-eye data set: no model parameter moves them).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kinecal.errors import InputError
from kinecal.kinematics.tree.system import is_system

Array = NDArray[np.float64]

__all__ = ["FLANGE", "WORLD", "FixedFrames", "LinkFrames", "LinkPoses", "check_link",
           "link_names"]

#: the measurement frame (a static camera or board)
WORLD = "world"
#: a serial arm's end frame (the tool frame when the model has one)
FLANGE = "flange"


@dataclass
class LinkPoses:
    """One link's pose per image.

    Attributes
    ----------
    R : ndarray, shape (n, 3, 3)
        ``link2world`` rotations.
    t : ndarray, shape (n, 3)
        Link origins in the world frame (length unit).
    G : ndarray, shape (n, 6, k) or None
        Derivative of ``(t, phi)`` with respect to the parameter columns asked for (None:
        the link does not move with the parameters, or no columns were asked for).
    moves : bool
        False for the world frame (identity everywhere).
    """

    R: Array
    t: Array
    G: Array | None
    moves: bool = True


def link_names(model) -> list[str]:
    """The link names a camera or board of `model` may hang from (module docstring)."""
    if is_system(model):
        tips = list(model.tips)
        extra = [FLANGE] if len(tips) == 1 else []
        return [WORLD, *extra, *tips, *[ln for ln in model.links if ln != model.root
                                          and ln not in tips]]
    return [WORLD, FLANGE]


def check_link(model, link: str, option: str = "--camera") -> str:
    """The link `link` resolved to what `LinkFrames` sweeps: ``world``, ``flange``, or a
    system link (a tip's name gives its link); `InputError` naming the choices."""
    link = str(link).strip()
    if is_system(model):
        if link in (WORLD, model.root):
            return WORLD
        if link == FLANGE and len(model.tips) == 1:
            return model.tip_link(model.tips[0])
        if link in model.tips:
            return model.tip_link(link)
        if link in model.links:
            return link
    elif link in (WORLD, FLANGE):
        return link
    shown = link_names(model)
    more = " ..." if len(shown) > 12 else ""
    raise InputError(f"link {link!r}: expected one of {', '.join(shown[:12])}{more} (world: a "
                     "static mount; flange: the arm's end frame)", option=option)


def _identity(n: int) -> LinkPoses:
    return LinkPoses(np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3)), None, False)


class LinkFrames:
    """Poses of a model's mounting links per image (module docstring).

    Parameters
    ----------
    model : SerialModel or SystemModel
    q : ndarray, shape (n, n_joints)
        Joint readings of every image (rad; prismatic: length unit).
    links : sequence of str
        Resolved link names (`check_link`).
    """

    def __init__(self, model, q: Array, links: Sequence[str]) -> None:
        self.model = model
        self.q = np.atleast_2d(np.asarray(q, dtype=float))
        self.links = list(dict.fromkeys(links))
        for link in self.links:
            if link != WORLD and not is_system(model) and link != FLANGE:
                raise InputError(f"link {link!r}: a serial arm's mounts are world or flange")

    @property
    def n(self) -> int:
        """Number of images."""
        return len(self.q)

    def poses(self, params: Array, columns: NDArray[np.intp] | None = None
              ) -> dict[str, LinkPoses]:
        """Every link's `LinkPoses` at `params` ``(n_params,)``, with the pose Jacobian of
        `columns` (parameter indices) when given."""
        out: dict[str, LinkPoses] = {}
        cols = None if columns is None else np.asarray(columns, dtype=np.intp)
        for link in self.links:
            if link == WORLD:
                out[link] = _identity(self.n)
                continue
            if is_system(self.model):
                sw = self.model.link_sweep(self.q, link, params)
            else:
                sw = self.model.sweep(self.q, params)
            G = None
            if cols is not None:
                G = np.transpose(sw.jacobian_t("pose", columns=cols), (2, 1, 0)) if cols.size \
                    else np.zeros((self.n, 6, 0))
            out[link] = LinkPoses(np.asarray(sw.rotations), np.asarray(sw.positions), G)
        return out

    def subset(self, rows: NDArray[np.intp]) -> LinkFrames:
        """The frames of the images `rows` only."""
        return LinkFrames(self.model, self.q[rows], self.links)


class FixedFrames:
    """Link poses given per image (module docstring).

    Parameters
    ----------
    poses : mapping of str to ndarray, shape (n, 4, 4)
        ``link2world`` of every image, per link other than ``world``.
    """

    def __init__(self, poses: Mapping[str, Array], n: int | None = None) -> None:
        self._poses = {k: np.asarray(v, dtype=float) for k, v in poses.items()}
        sizes = {len(v) for v in self._poses.values()}
        if n is None:
            if len(sizes) != 1:
                raise InputError("link poses: expected one pose per image for every link")
            n = sizes.pop()
        self._n = int(n)
        self.links = [WORLD, *self._poses]
        self.model = None

    @property
    def n(self) -> int:
        return self._n

    def poses(self, params: Array | None = None, columns: NDArray[np.intp] | None = None
              ) -> dict[str, LinkPoses]:
        out = {WORLD: _identity(self.n)}
        for link, T in self._poses.items():
            G = None if columns is None else np.zeros((self.n, 6, len(columns)))
            out[link] = LinkPoses(T[:, :3, :3], T[:, :3, 3], G)
        return out

    def subset(self, rows: NDArray[np.intp]) -> FixedFrames:
        return FixedFrames({k: v[rows] for k, v in self._poses.items()}, len(rows))
