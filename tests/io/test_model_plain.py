"""Model files checked without pydantic (`kinecal.io.model_plain`) give exactly what the
pydantic schema gives, or defer to it: on every bundled model and on many altered ones."""

import copy
import math

import numpy as np
import pytest
from pydantic import ValidationError

from kinecal.io.bundled import bundled_names
from kinecal.io.model_plain import ENTRY_FIELDS, FILE_FIELDS, plain_entry, plain_model_file
from kinecal.io.model_schema import (
    FrameSpec,
    JointSpec,
    ModelFile,
    URDFFrameSpec,
    URDFJointSpec,
    entry_spec,
)
from kinecal.io.models import load_model, model_path, read_yaml


def _schema(data):
    """The pydantic answer in `plain_model_file`'s form, or None on a schema error."""
    try:
        spec = ModelFile.model_validate(data)
    except ValidationError:
        return None
    out = dict(spec)
    out["tolerances"] = dict(spec.tolerances)
    return out


def _schema_entry(convention, entry):
    try:
        return entry_spec(convention, entry).model_validate(entry).model_dump(exclude_none=True)
    except ValidationError:
        return None


def _same(a, b):
    """Equal values of equal types (an int where the schema gives a float is a failure)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return type(a) is type(b) and len(a) == len(b) and all(map(_same, a, b))
    return type(a) is type(b) and (a == b or (isinstance(a, float) and math.isnan(a)
                                              and math.isnan(b)))


def _check(data):
    plain = plain_model_file(copy.deepcopy(data))
    if plain is not None:  # accepted: the schema must accept it and agree in every field
        schema = _schema(copy.deepcopy(data))
        assert schema is not None and _same(plain, schema), (data, plain, schema)
        for entry in data["joints"]:
            p = plain_entry(data["convention"], entry)
            if p is not None:
                s = _schema_entry(data["convention"], entry)
                assert s is not None and _same(p, s), (entry, p, s)
    return plain is not None


MODELS = bundled_names("model")


def test_the_tables_name_the_schema_fields_and_defaults():
    for (urdf, frame), fields in ENTRY_FIELDS.items():
        cls = {(False, False): JointSpec, (True, False): URDFJointSpec,
               (False, True): FrameSpec, (True, True): URDFFrameSpec}[(urdf, frame)]
        assert [f for f, _, _ in fields] == list(cls.model_fields)
        for name, _, default in fields:
            info = cls.model_fields[name]
            if info.is_required():
                assert default is not None and not isinstance(default, float | str | tuple)
            else:
                assert _same(default, info.default), (cls, name)
    top = [f for f, _, _ in FILE_FIELDS]
    assert set(top) < set(ModelFile.model_fields)


@pytest.mark.parametrize("name", MODELS)
def test_bundled_models_are_plain_and_load_as_with_the_schema(name):
    data = read_yaml(model_path(name))
    if data.get("kind") == "system":
        pytest.skip("a system file")
    assert _check(data)  # every bundled model takes the fast path
    for entry in data["joints"]:
        assert plain_entry(data["convention"], entry) is not None


def _mutations(data, rng):
    """Altered copies of a model file's mapping: other types, values, keys."""
    odd = [None, True, False, "1.5", "x", 0, -1, 2.5, float("nan"), float("inf"), [], {},
           [1.0, 2.0], [1, 2, 3], (1.0, 2.0, 3.0), "revolute", "prismatic", "continuous",
           "deg", "rad", "m", "mm", "urdf", "hayati", 1e300, 1 << 70]
    keys = list(data) + ["kind", "extra", "joints", "tolerances", "markers", "fixed"]
    for _ in range(60):
        d = copy.deepcopy(data)
        k = keys[rng.integers(len(keys))]
        what = rng.integers(4)
        if what == 0:
            d.pop(k, None)
        elif what == 1:
            d[k] = odd[rng.integers(len(odd))]
        elif what == 2 and d.get("joints"):  # alter one chain entry
            j = d["joints"][rng.integers(len(d["joints"]))]
            fields = list(j) + ["beta", "type", "frame", "calibrate", "axis", "bogus", "name"]
            f = fields[rng.integers(len(fields))]
            if rng.random() < 0.3:
                j.pop(f, None)
            else:
                j[f] = odd[rng.integers(len(odd))]
        else:  # structured values
            choice = rng.integers(4)
            if choice == 0:
                d["tolerances"] = {"length": odd[rng.integers(len(odd))], "angle": 0.1}
            elif choice == 1:
                d["joint_limits"] = [[-1, 1]] * rng.integers(0, 8) + [odd[rng.integers(len(odd))]]
            elif choice == 2:
                d["markers"] = {"A": [0, 0, odd[rng.integers(len(odd))]]}
            else:
                d["tool"] = [1.0] * int(rng.integers(0, 10))
        yield d


@pytest.mark.parametrize("name", ["ur5", "irb120", "kr6-craig", "puma560", "ur10e"])
def test_altered_models_agree_with_the_schema_or_defer(name):
    data = read_yaml(model_path(name))
    rng = np.random.default_rng(7)
    taken = sum(_check(d) for d in _mutations(data, rng))
    assert taken > 5  # the fast path sees some of them (valid alterations)


def test_urdf_convention_entries_agree():
    entries = [{"name": "j1", "x": 1, "axis": [0, 0, 1]}, {"name": "j2", "type": "continuous"},
               {"name": "j3", "axis": [0, 0, 1.5], "effort": 3, "parent": "a", "child": "b"},
               {"frame": "f", "roll": 1, "calibrate": True, "parent": "p"},
               {"frame": "f", "rx": 1}, {"name": "j", "axis": [0, 1]}, {"name": "j", "axis": "z"},
               {"name": 5}, {"frame": "f", "calibrate": 1}, {"name": "j", "velocity": None}]
    for e in entries:
        p = plain_entry("urdf", e)
        s = _schema_entry("urdf", e)
        assert p is None or _same(p, s), (e, p, s)
    assert plain_entry("urdf", entries[0]) is not None


def test_load_model_errors_still_name_the_key(tmp_path):
    """A value the fast path defers on gets the schema's message, as before."""
    f = tmp_path / "m.yaml"
    f.write_text("name: m\nconvention: dh\nangle_unit: deg\njoints:\n"
                 "  - {theta: 0, d: 1, a: 0, alpha: x}\n")
    from kinecal.errors import InputError

    with pytest.raises(InputError, match=r"joints\.0\.alpha"):
        load_model(f)
    f.write_text("name: m\nconvention: dh\nangle_unit: deg\nbogus: 1\njoints:\n"
                 "  - {theta: 0, d: 1, a: 0, alpha: 0}\n")
    with pytest.raises(InputError, match="bogus"):
        load_model(f)
