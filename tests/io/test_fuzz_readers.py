"""Every reader turns arbitrary bad files into InputError: never another exception.

Hypothesis mutates valid files (cells replaced, lines dropped or duplicated, bytes flipped)
and writes random text; each reader must either return or raise `kinecal.InputError`.
"""

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import kinecal
from kinecal.batch.jobs import load_jobs
from kinecal.calibration.serial.simulate import simulate
from kinecal.errors import InputError
from kinecal.io.geometry import load_geometry
from kinecal.io.handeye import read_handeye_pairs, write_handeye_csv, write_handeye_yaml
from kinecal.io.measurements import read_measurements, write_measurements
from kinecal.io.models import load_model, model_path
from kinecal.spatial import matrix_from_axis_angle, transform_from

MODEL = kinecal.load_model("irb120")
TMP = Path(tempfile.mkdtemp(prefix="kinecal-fuzz-"))


def _valid_texts() -> dict[str, str]:
    sim = simulate(MODEL, 4, errors="zero", rng=0)
    write_measurements(TMP / "m.csv", sim.data, MODEL)
    rng = np.random.default_rng(0)
    T = transform_from(matrix_from_axis_angle(rng.normal(size=(4, 3))), rng.normal(size=(4, 3)))
    write_handeye_csv(TMP / "h.csv", T, T)
    write_handeye_yaml(TMP / "h.yml", T, T)
    geometry = Path(str(kinecal.io.geometry.geometry_path("liu2008-cmm"))).read_text()
    return {
        "m.csv": (TMP / "m.csv").read_text(),
        "h.csv": (TMP / "h.csv").read_text(),
        "h.yml": (TMP / "h.yml").read_text(),
        "model.yaml": model_path("irb120").read_text(),
        "geometry.yaml": geometry,
        "jobs.yaml": "study: {model: irb120, methods: [lm], seeds: [0], noise: [0.01], "
                     "poses: [20], validation_poses: 10}\n",
    }


VALID = _valid_texts()
READERS = {
    "m.csv": lambda p: read_measurements(p, MODEL),
    "h.csv": read_handeye_pairs,
    "h.yml": read_handeye_pairs,
    "model.yaml": load_model,
    "geometry.yaml": load_geometry,
    "jobs.yaml": load_jobs,
}

junk = st.sampled_from(["", "nan", "inf", "x", "1e999", "-", ",", "\x00", "{", "[1, 2",
                        "q1", ":", "!!python/object:os.system", "'", "1,2,3", "\t", "é"])


@st.composite
def mutated(draw):
    name = draw(st.sampled_from(sorted(VALID)))
    lines = VALID[name].splitlines()
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["replace", "drop", "duplicate", "cell", "truncate"]))
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        if kind == "replace":
            lines[i] = draw(junk)
        elif kind == "drop":
            del lines[i]
        elif kind == "duplicate":
            lines.insert(i, lines[i])
        elif kind == "cell":
            cells = lines[i].split(",")
            cells[draw(st.integers(0, len(cells) - 1))] = draw(junk)
            lines[i] = ",".join(cells)
        else:
            lines[i] = lines[i][: draw(st.integers(0, max(len(lines[i]) - 1, 0)))]
    return name, "\n".join(lines) + "\n"


def _check(name: str, text: str) -> None:
    path = TMP / f"fuzz-{name}"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        READERS[name](path)
    except InputError as exc:
        assert "\n" not in exc.one_line()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutated_files_raise_only_input_error(case):
    _check(*case)


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(sorted(VALID)), st.text(max_size=200))
def test_random_text_raises_only_input_error(name, text):
    _check(name, text)
