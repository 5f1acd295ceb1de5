"""check_paths: outputs never overwrite inputs or each other."""

import pytest

from kinecal.cli._common import check_paths
from kinecal.errors import InputError


def test_output_equal_to_input_is_refused(tmp_path):
    data = tmp_path / "meas.csv"
    data.write_text("q1\n0\n")
    with pytest.raises(InputError, match="also the input DATA"):
        check_paths({"DATA": data}, {"--out": tmp_path / "." / "meas.csv"})
    link = tmp_path / "link.csv"
    link.symlink_to(data)
    with pytest.raises(InputError, match="also the input DATA"):
        check_paths({"DATA": data}, {"--out": link})
    assert data.read_text() == "q1\n0\n"


def test_two_outputs_on_one_path_are_refused(tmp_path):
    with pytest.raises(InputError, match="also given to --out") as exc:
        check_paths({}, {"--out": tmp_path / "r.json", "--report": tmp_path / "r.json"})
    assert exc.value.option == "--report"


def test_directories_and_missing_folders_are_refused(tmp_path):
    with pytest.raises(InputError, match="is a directory"):
        check_paths({}, {"--out": tmp_path})
    with pytest.raises(InputError, match="does not exist"):
        check_paths({}, {"--out": tmp_path / "nope" / "r.json"})


def test_distinct_paths_and_bundled_inputs_pass(tmp_path):
    check_paths({"DATA": "ur5-laser-tracker:grid", "--validate": None},
                {"--out": tmp_path / "a.json", "--report": tmp_path / "a.html",
                 "--model-out": None})
