"""Safe YAML reading for every layer: `load_yaml` (one document, alias bombs and deep
nesting refused before the document is built) and `read_yaml_mapping` (a file whose top
level is a mapping). (This module sits beside `kinecal._files`, below all layers.)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kinecal._files import read_text
from kinecal.errors import InputError

__all__ = ["MAX_YAML_ALIAS_NODES", "load_yaml", "read_yaml_mapping"]

#: YAML aliases may add at most this many nodes to a document once expanded (a "billion
#: laughs" file of 1 kB expands to 10^9 nodes; a real jobs or model file has no need of more)
MAX_YAML_ALIAS_NODES = 1_000_000


def _children(node: Any) -> list:
    import yaml

    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    return []


def _alias_growth(root: Any) -> int | None:
    """Nodes the aliases add to the document rooted at `root` when expanded (None: a
    recursive alias, i.e. infinitely many). Iterative: no recursion limit."""
    size: dict[int, int] = {}
    open_: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, closing = stack.pop()
        key = id(node)
        if closing:
            size[key] = 1 + sum(size[id(c)] for c in _children(node))
            open_.discard(key)
            continue
        if key in size:
            continue
        open_.add(key)
        stack.append((node, True))
        for child in _children(node):
            if id(child) in open_:
                return None
            if id(child) not in size:
                stack.append((child, False))
    return size[id(root)] - len(size)


def load_yaml(text: str, file: str | Path | None = None, loader: type | None = None) -> Any:
    """Parse one YAML document safely (`yaml.SafeLoader`, or the given subclass).

    Anchors and aliases are allowed, but a document whose aliases expand it by more than
    `MAX_YAML_ALIAS_NODES` nodes ("billion laughs") or refer to themselves is refused
    before it is built, and so is nesting deeper than Python's recursion limit.

    Raises
    ------
    InputError
        Not valid YAML (with the line), an alias bomb, or too deep nesting; names `file`.
    """
    import yaml

    ld = None
    try:
        ld = (loader or yaml.SafeLoader)(text)  # its reader already refuses control chars
        node = ld.get_single_node()
        if node is None:
            return None
        growth = _alias_growth(node)
        if growth is None:
            raise InputError("YAML alias refers to itself (a recursive document); expected "
                             "plain data", file=file)
        if growth > MAX_YAML_ALIAS_NODES:
            raise InputError(f"YAML aliases expand the document by {growth:.3g} nodes, more "
                             f"than the {MAX_YAML_ALIAS_NODES:,} allowed (an alias bomb?)",
                             file=file)
        return ld.construct_document(node)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None)
        raise InputError(f"not valid YAML{where}" + (f": {problem}" if problem else ""),
                         file=file) from None
    except RecursionError:
        raise InputError("YAML nested too deeply", file=file) from None
    finally:
        if ld is not None:
            ld.dispose()


def read_yaml_mapping(path: str | Path, text: str | None = None) -> dict:
    """The YAML mapping in `path` (or in `text` read from it); `InputError` otherwise.

    Parsed by `load_yaml` (safe, alias bombs refused).
    """
    text = read_text(path) if text is None else text
    data = load_yaml(text, path)
    if not isinstance(data, dict):
        raise InputError("expected a YAML mapping (key: value) at the top level", file=path)
    return data
