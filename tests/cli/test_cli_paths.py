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


def _images(tmp_path):
    folder = tmp_path / "images"
    (folder / "sub").mkdir(parents=True)
    for name in ("a.png", "b.PNG", "notes.txt", "sub/old.json"):
        (folder / name).write_bytes(b"keep")
    return folder


def test_a_folder_input_protects_the_files_in_it(tmp_path):
    folder = _images(tmp_path)
    reads = {"IMAGES_DIR": (".png", ".jpg")}
    link = tmp_path / "out.json"
    link.symlink_to(folder / "notes.txt")
    for out, words in ((folder / "a.png", "inside the input folder IMAGES_DIR"),
                       (folder / "notes.txt", "inside the input folder"),  # any file in it
                       (folder / "sub" / "old.json", "inside the input folder"),  # any depth
                       (tmp_path / "images" / ".." / "images" / "b.PNG", "inside"),
                       (link, "inside the input folder"),  # a link into the folder
                       (folder / "new.jpg", "which the command reads as input"),
                       (folder / "NEW.JPG", "which the command reads as input")):
        with pytest.raises(InputError, match=words):
            check_paths({"IMAGES_DIR": folder}, {"--report": out}, reads=reads)
    # new files that the command does not read, and anything outside the folder, pass
    check_paths({"IMAGES_DIR": folder}, {"--out": folder / "result.json",
                                         "--report": folder / "sub" / "new.png"}, reads=reads)
    check_paths({"IMAGES_DIR": folder}, {"--out": tmp_path / "a.png"}, reads=reads)
    assert all((folder / n).read_bytes() == b"keep" for n in ("a.png", "b.PNG", "notes.txt"))


def test_handeye_images_never_writes_into_its_images(tmp_path, capsys):
    from kinecal.cli import main

    folder = _images(tmp_path)
    poses = tmp_path / "poses.csv"
    poses.write_text("image,flange_x,flange_y,flange_z,flange_qw,flange_qx,flange_qy,"
                     "flange_qz\na.png,0,0,0,1,0,0,0\n")
    base = ["handeye-images", str(folder), str(poses), "--board", "chessboard:9x6:20"]
    for option, out, words in (("--out", folder / "a.png", "inside the input folder"),
                               ("--report", folder / "b.PNG", "inside the input folder"),
                               ("--report", folder / "report.png", "reads as input"),
                               ("--out", folder / "notes.txt", "inside the input folder")):
        assert main([*base, option, str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"kinecal: error: option {option}: ") and words in err
        assert len(err.strip().splitlines()) == 1
    assert all((folder / n).read_bytes() == b"keep" for n in ("a.png", "b.PNG", "notes.txt"))
    assert not (folder / "report.png").exists()
    # a new result file beside the images passes the path check (then the dummy images fail)
    assert main([*base, "--out", str(folder / "result.json")]) == 2
    assert "input folder" not in capsys.readouterr().err
