"""The bundled-machine index (top-level keys read as text) agrees with parsing every file."""

import yaml

from kinecal.io.bundled import _kind, bundled_index, bundled_names, robots_dir


def _parsed_kind(data):
    if isinstance(data, dict) and data.get("kind") == "stewart":
        return "geometry"
    if isinstance(data, dict) and data.get("kind") == "system":
        return "system"
    if isinstance(data, dict) and data.get("convention") is not None:
        return "model"
    return None


def test_index_matches_yaml_parsing_of_every_bundled_file():
    files = sorted(robots_dir().glob("*.yaml"))
    assert files
    expected = {}
    for p in files:
        kind = _parsed_kind(yaml.safe_load(p.read_text(encoding="utf-8")))
        if kind is not None:
            expected[p.stem] = kind
    assert bundled_index() == expected
    assert "ur5" in bundled_names("model") and "liu2008-cmm" in bundled_names("geometry")
    assert "rail-cell" in bundled_names("system") and "rail-cell" not in bundled_names("model")


def test_kind_from_top_level_keys_only():
    assert _kind("name: a\nconvention: dh\njoints: []\n") == "model"
    assert _kind("name: a\nkind: stewart  # CMM\n") == "geometry"
    assert _kind("name: a\nkind: 'stewart'\n") == "geometry"
    assert _kind("name: a\n  convention: dh\n") is None  # nested, not top level
    assert _kind("name: a\nconvention: null\n") is None
    assert _kind("name: a\nconvention:\n") is None
    assert _kind("name: a\nkind: stewartish\n") is None
    assert _kind("name: a\nkind: system\nparts: []\n") == "system"
    for text in ("name: a\nconvention: dh\n", "kind: stewart\n", "convention: null\n"):
        assert _kind(text) == _parsed_kind(yaml.safe_load(text))
