"""A ROS 1 or ROS 2 bag opened through ``rosbags``: topics, types, message streams.

ROS 2 bags are a folder with ``metadata.yaml`` (or one ``.db3`` / ``.mcap`` file), ROS 1 bags
a ``.bag`` file. Messages are streamed in the bag's order, raw; each is deserialized only
when the caller asks (`Bag.decode`), so large images cost nothing until one is kept.
Every failure of the library (a truncated or corrupt file, an unknown message type) becomes
an `InputError` naming the bag.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from pathlib import Path

from kinecal.errors import InputError
from kinecal.io.ros import require_rosbags
from kinecal.io.ros.messages import ACCEPTED, EXTRA_TYPES

__all__ = ["Bag", "bag_root", "check_regular", "is_bag_path"]

_BAG_SUFFIXES = (".bag", ".db3", ".mcap")
#: a Python exception's repr (``KeyError('version')``) or a one-item tuple (``('text',)``)
#: inside the library's message: the text alone is kept
_REPR = re.compile(r"\b[A-Za-z_]\w*(?:Error|Exception)\((.*?)\)|\(('.*?'),\)")


def _library_text(exc: Exception) -> str:
    """The library's message of `exc` on one line, without Python reprs."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return _REPR.sub(lambda m: m.group(1) or m.group(2), text)


def bag_root(path: str | Path) -> Path:
    """What a bag reads: its folder when `path` is the ``.db3`` / ``.mcap`` file of a ROS 2
    bag folder (its ``metadata.yaml`` beside it), else `path` (outputs must stay out)."""
    p = Path(path)
    if p.suffix.lower() in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
        return p.parent
    return p


def is_bag_path(path: str | Path) -> bool:
    """A ROS 2 bag folder (``metadata.yaml`` inside) or a ``.bag``/``.db3``/``.mcap`` file."""
    p = Path(path)
    return p.suffix.lower() in _BAG_SUFFIXES or (p / "metadata.yaml").exists()


def check_regular(path: Path) -> None:
    """`InputError` unless the bag's files are regular files (a FIFO or a device would block
    the reader, or never end): the file itself, or a folder's ``metadata.yaml`` and data
    files."""
    files = [path] if not path.is_dir() else [p for p in path.iterdir()
                                               if p.name == "metadata.yaml"
                                               or p.suffix.lower() in _BAG_SUFFIXES]
    for f in files:
        if f.exists() and not f.is_file():
            what = "a FIFO (named pipe)" if f.is_fifo() else "not a regular file"
            raise InputError(f"{f.name} is {what}: expected a bag file on disk", file=path)


class Bag:
    """An open bag (a context manager).

    Parameters
    ----------
    path : str or Path
        The bag (see the module docstring).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise InputError("bag not found", file=self.path)
        if not is_bag_path(self.path):
            raise InputError("not a ROS bag: expected a ROS 2 bag folder (with metadata.yaml), "
                             "a .db3 or .mcap file, or a ROS 1 .bag file", file=self.path)
        check_regular(self.path)
        highlevel = require_rosbags()
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore

        store = get_typestore(Stores.ROS2_HUMBLE)
        for name, text in EXTRA_TYPES.items():  # messages no ROS distribution defines
            if name not in store.types:
                store.register(get_types_from_msg(text, name))
        self._reader = self._call(highlevel.AnyReader, [self.path], default_typestore=store)
        self._open = False

    def _call(self, fn, *args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except InputError:
            raise
        except Exception as exc:  # the library's own errors: a bad or cut bag
            raise InputError(f"cannot read the bag: {_library_text(exc)}",
                             file=self.path) from None

    def __enter__(self) -> Bag:
        self._call(self._reader.open)
        self._open = True
        return self

    def __exit__(self, *exc) -> None:
        if self._open:
            try:
                self._reader.close()
            except Exception:  # closing a broken bag must not mask its error
                pass
            self._open = False

    @property
    def topics(self) -> dict[str, str]:
        """``{topic: message type}``."""
        return {c.topic: c.msgtype for c in self._reader.connections}

    def check_topic(self, topic: str, option: str) -> str:
        """The type of `topic`; `InputError` when the bag lacks it or its type is not one
        `option` takes."""
        topics = self.topics
        if topic not in topics:
            listed = ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "none"
            raise InputError(f"topic {topic!r} is not in the bag {self.path} (topics: "
                             f"{listed})", option=option)
        kind = topics[topic]
        if kind not in ACCEPTED[option]:
            raise InputError(f"topic {topic} has type {kind}; {option} takes "
                             f"{' or '.join(ACCEPTED[option])}", option=option)
        return kind

    def stream(self, topics: Sequence[str]) -> Iterator[tuple[str, str, int, bytes]]:
        """``(topic, msgtype, bag_time_ns, raw)`` of every message on `topics`, in order."""
        wanted = set(topics)
        conns = [c for c in self._reader.connections if c.topic in wanted]
        if not conns:
            return
        gen = self._call(self._reader.messages, connections=conns)
        while True:
            try:
                con, t, raw = next(gen)
            except StopIteration:
                return
            except Exception as exc:
                raise InputError("cannot read the bag (truncated or corrupt?): "
                                 f"{_library_text(exc)}", file=self.path) from None
            yield con.topic, con.msgtype, int(t), raw

    def decode(self, raw: bytes, msgtype: str):
        """The message of `raw` (deserialized by rosbags)."""
        return self._call(self._reader.deserialize, raw, msgtype)
