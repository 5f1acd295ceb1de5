"""A camera rig on the command line: ``--camera NAME:LINK[:intrinsics.yaml]`` and ``--board
NAME:LINK:SPEC``, each repeatable.

``LINK`` is ``world`` (a static camera, a board on a table), ``flange`` (the arm's end
frame) or any link of a robot system (a head link, another arm's tip, a positioner's
table; `kinecal.calibration.camera.rig_frames`). A camera's intrinsics file is optional:
without it its intrinsics are estimated from its own images and refined with the rest.
``SPEC`` is a board spec of `kinecal.vision.boards` (``chessboard:9x6:25``,
``charuco:7x5:40:30:DICT_5X5_100[:FIRST]``).

Several boards may show in one image when they can be told apart: ChArUco boards whose
marker ids do not overlap (a ``FIRST`` id per board). Chessboards and circle grids carry
no ids: with several of them, each image's ``board`` column names the one it shows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from kinecal.calibration.camera.rig_frames import check_link
from kinecal.calibration.camera.rig_pixels import Mount
from kinecal.errors import InputError
from kinecal.vision.boards import Board, Charuco, parse_board
from kinecal.vision.intrinsics import CameraIntrinsics, read_intrinsics

__all__ = ["BOARD_KINDS", "Rig", "RigBoard", "RigCamera", "is_mounted_board", "parse_rig"]

#: the first field of a plain board spec (``--board SPEC`` of the one-camera forms)
BOARD_KINDS = ("chessboard", "charuco", "acircles", "circles", "modcircles")


@dataclass
class RigCamera:
    """A camera of a rig: its name, link and (optional) intrinsics."""

    name: str
    link: str
    intrinsics: CameraIntrinsics | None = None
    intrinsics_file: str | None = None


@dataclass
class RigBoard:
    """A board of a rig: its name, link and geometry."""

    name: str
    link: str
    board: Board


def is_mounted_board(text: str) -> bool:
    """Whether a ``--board`` value is ``NAME:LINK:SPEC`` (a rig's) rather than ``SPEC``."""
    return str(text).split(":", 1)[0].strip().lower() not in BOARD_KINDS


def _name(text: str, what: str, option: str) -> str:
    name = text.strip()
    if not name or not all(ch.isalnum() or ch in "_-." for ch in name):
        raise InputError(f"{what} name {text!r}: expected letters, digits, '_', '-' or '.'",
                         option=option)
    return name


def parse_camera(text: str, read: bool = True) -> RigCamera:
    """``NAME:LINK[:intrinsics.yaml]`` -> `RigCamera` (the file read when `read`)."""
    parts = str(text).split(":", 2)
    if len(parts) < 2 or not parts[1].strip():
        raise InputError(f"{text!r}: expected NAME:LINK[:intrinsics.yaml] (e.g. left:world or "
                         "head:head_camera_link:head.yaml)", option="--camera")
    name = _name(parts[0], "camera", "--camera")
    path = parts[2].strip() if len(parts) == 3 and parts[2].strip() else None
    intr = read_intrinsics(Path(path)) if path is not None and read else None
    return RigCamera(name, parts[1].strip(), intr, path)


def parse_mounted_board(text: str) -> RigBoard:
    """``NAME:LINK:SPEC`` -> `RigBoard`."""
    parts = str(text).split(":", 2)
    if len(parts) < 3 or parts[0].strip().lower() in BOARD_KINDS:
        raise InputError(f"{text!r}: expected NAME:LINK:SPEC (e.g. "
                         "held:flange:chessboard:9x6:25)", option="--board")
    return RigBoard(_name(parts[0], "board", "--board"), parts[1].strip(),
                    parse_board(parts[2]))


@dataclass
class Rig:
    """The cameras and boards of a rig (module docstring)."""

    cameras: list[RigCamera]
    boards: list[RigBoard]
    links: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.cameras or not self.boards:
            raise InputError("a rig needs at least one camera (--camera NAME:LINK) and one "
                             "board (--board NAME:LINK:SPEC)", option="--camera")
        for what, items in (("camera", self.cameras), ("board", self.boards)):
            names = [i.name for i in items]
            twice = sorted({n for n in names if names.count(n) > 1})
            if twice:
                raise InputError(f"{what} name(s) {', '.join(twice)} given twice",
                                 option=f"--{what}")
        charuco = [b for b in self.boards if isinstance(b.board, Charuco)]
        for i, a in enumerate(charuco):
            for b in charuco[i + 1:]:
                if a.board.dictionary == b.board.dictionary and \
                        set(a.board.marker_ids) & set(b.board.marker_ids):
                    raise InputError(
                        f"boards {a.name} and {b.name} use the same {a.board.dictionary} "
                        f"marker ids ({a.board.marker_ids.start}.. and "
                        f"{b.board.marker_ids.start}..): an image could not tell them apart; "
                        "give the second its first marker id (charuco:...:DICT:FIRST, e.g. "
                        f":{a.board.marker_ids.stop})", option="--board")

    @property
    def camera_names(self) -> list[str]:
        return [c.name for c in self.cameras]

    @property
    def board_names(self) -> list[str]:
        return [b.name for b in self.boards]

    def told_apart(self) -> bool:
        """Whether every board can be found in an image showing several (all ChArUco with
        disjoint ids, or one board)."""
        return len(self.boards) == 1 or all(isinstance(b.board, Charuco) for b in self.boards)

    def mounts(self, model) -> tuple[list[Mount], list[Mount]]:
        """The cameras' and boards' `Mount` with their links resolved on `model`
        (`InputError` naming the link choices)."""
        cams = [Mount(c.name, check_link(model, c.link, "--camera")) for c in self.cameras]
        boards = [Mount(b.name, check_link(model, b.link, "--board")) for b in self.boards]
        return cams, boards


def parse_rig(cameras: Sequence[str], boards: Sequence[str], read: bool = True) -> Rig:
    """The rig of ``--camera`` and ``--board`` values (module docstring)."""
    return Rig([parse_camera(c, read) for c in cameras],
               [parse_mounted_board(b) for b in boards])
