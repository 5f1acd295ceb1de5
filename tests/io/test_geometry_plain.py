"""Stewart geometry files checked without pydantic (`kinecal.io.geometry_plain`) give what
the pydantic schema gives, or defer to it: on the bundled geometries and many altered ones;
errors keep the schema's words."""

import copy

import numpy as np
import pytest
from pydantic import ValidationError

from kinecal.errors import InputError
from kinecal.io.geometry import bundled_geometries, geometry_path, load_geometry
from kinecal.io.geometry_plain import FIELDS, plain_geometry
from kinecal.io.geometry_schema import GeometrySpec
from kinecal.io.models import read_yaml


def _same(a, b):
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(map(_same, a, b))
    return type(a) is type(b) and a == b


def _check(data):
    plain = plain_geometry(copy.deepcopy(data))
    if plain is None:
        return False
    spec = GeometrySpec.model_validate(copy.deepcopy(data))  # must accept it
    mine, theirs = vars(plain), dict(spec)
    assert list(mine) == list(theirs)
    assert all(_same(mine[k], theirs[k]) for k in mine), (data, mine, theirs)
    return True


def test_fields_are_the_schemas():
    assert list(FIELDS) == list(GeometrySpec.model_fields)


@pytest.mark.parametrize("name", bundled_geometries())
def test_bundled_geometries_are_plain(name):
    assert _check(read_yaml(geometry_path(name)))


def _joints_form(data):
    geom = load_geometry("liu2008-cmm")
    d = {k: v for k, v in data.items() if k not in ("base_radius", "platform_radius",
                                                    "base_short_edge_angle",
                                                    "platform_short_edge_angle")}
    d["base_joints"] = geom.base_joints.tolist()
    d["platform_joints"] = geom.platform_joints.tolist()
    d["leg_offsets"] = [0.0, 0.001, 0, 0, 0, -0.002]
    return d


def test_altered_geometries_agree_with_the_schema_or_defer():
    base = read_yaml(geometry_path("liu2008-cmm"))
    rng = np.random.default_rng(3)
    odd = [None, True, "1", "x", 0, -1, 2.5, 200, float("nan"), float("inf"), [], [1, 2],
           [0.9, 0.8], [0.5, 0.9], [[1, 2, 3]] * 6, [1.0] * 6, "stewart", "mm", "rad", "deg",
           "m", {}]
    taken = 0
    for form in (base, _joints_form(base)):
        assert _check(form)
        keys = [*FIELDS, "bogus"]
        for _ in range(300):
            d = copy.deepcopy(form)
            for _ in range(rng.integers(1, 3)):
                k = keys[rng.integers(len(keys))]
                if rng.random() < 0.3:
                    d.pop(k, None)
                else:
                    d[k] = copy.deepcopy(odd[rng.integers(len(odd))])
            try:
                taken += _check(d)
            except ValidationError as exc:  # plain accepted what the schema refuses
                raise AssertionError(d) from exc
    assert taken > 20


def test_errors_keep_the_schemas_words(tmp_path):
    f = tmp_path / "g.yaml"
    f.write_text("kind: stewart\nbase_radius: 0.5\nplatform_radius: -1\n"
                 "base_short_edge_angle: 30\nplatform_short_edge_angle: 30\n"
                 "leg_range: [0.75, 0.97]\n")
    with pytest.raises(InputError, match="platform_radius: expected a radius > 0"):
        load_geometry(f)
    f.write_text("kind: stewart\nbase_radius: 0.5\nleg_range: [0.75, 0.97]\n")
    with pytest.raises(InputError, match="missing platform_radius"):
        load_geometry(f)
