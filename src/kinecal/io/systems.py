"""Loading robot systems: a URDF tree with several tips, or a ``kind: system`` file.

`load_machine` is what a command's MODEL argument goes through when the command takes
systems: a serial chain stays a `SerialModel` exactly as `kinecal.io.models.load_model`
reads it, and a system becomes a `SystemModel`:

* a URDF with two or more ``--tip-link`` (`kinecal.io.urdf_tree`), or with one tip whose
  chain holds a coupled (mimic) joint;
* a ``kind: system`` file, a path or a bundled name (`kinecal.io.system_file`); its tips
  are its parts.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from kinecal.errors import InputError
from kinecal.io.bundled import bundled_index, resolve_machine_file
from kinecal.io.models import is_urdf_path, load_model
from kinecal.kinematics.serial.model import SerialModel
from kinecal.kinematics.tree.system import SystemModel

__all__ = ["is_system_file", "is_system_spec", "load_machine", "load_system"]


def is_system_file(spec: str | Path) -> bool:
    """True for a ``kind: system`` file (a path or a bundled name)."""
    if bundled_index().get(str(spec)) == "system":
        return True
    path = Path(spec)
    if path.suffix.lower() not in (".yaml", ".yml") or not path.is_file():
        return False
    try:
        head = path.read_text(encoding="utf-8", errors="replace")[:65536]
    except OSError:
        return False
    from kinecal.io.bundled import _kind

    return _kind(head) == "system"


def _urdf_coupled(path: str | Path, base_link: str | None, tip: str | None) -> bool:
    """Whether the chain `base_link` -> `tip` of a URDF holds a mimic joint (a file
    without any ``<mimic`` tag is not parsed)."""
    from kinecal.io.urdf import read_urdf
    from kinecal.io.urdf_chain import chain_path

    try:
        if b"<mimic" not in Path(path).read_bytes():
            return False
    except OSError:
        return False  # the URDF reader reports it
    urdf = read_urdf(path)
    return any(j.mimic is not None and j.type != "fixed"
               for j in chain_path(urdf, base_link, tip, Path(path)))


def load_system(spec: str | Path, tips: Sequence[str] = (), *,
                base_link: str | None = None) -> SystemModel:
    """A system from a URDF and its tip links, or from a system file (module docstring).

    For a system file, `tips` (part names) must be among its parts; every part is a tip of
    the model returned (the caller picks the chains it works on).
    """
    tips = list(tips)
    if is_urdf_path(spec):
        from kinecal.io.urdf_tree import load_urdf_system

        return load_urdf_system(spec, tips, base_link=base_link)
    if base_link is not None:
        raise InputError("--base-link applies to URDF models only", option="--base-link")
    from kinecal.io.system_file import load_system_file

    system = load_system_file(resolve_machine_file(spec, "system"))
    for tip in tips:
        system.tip_number(tip)
    return system


def is_system_spec(spec: str | Path, base_link: str | None = None,
                   tips: Sequence[str] = ()) -> bool:
    """Whether `load_machine` makes a system of `spec` and `tips` (module docstring)."""
    tips = [t for t in tips if t is not None]
    if is_system_file(spec):
        return True
    return bool(is_urdf_path(spec) and Path(spec).is_file() and (
        len(tips) > 1 or _urdf_coupled(spec, base_link, tips[0] if tips else None)))


def load_machine(spec: str | Path, *, base_link: str | None = None,
                 tips: Sequence[str] = ()) -> SerialModel | SystemModel:
    """A serial model or a system, whichever `spec` and `tips` make (module docstring)."""
    tips = [t for t in tips if t is not None]
    if is_system_spec(spec, base_link, tips):
        return load_system(spec, tips, base_link=base_link)
    if len(tips) > 1:
        raise InputError(f"--tip-link given {len(tips)} times: several tips make a system of "
                         "a URDF tree; this model is not a URDF", option="--tip-link")
    return load_model(spec, base_link=base_link, tip_link=tips[0] if tips else None)
