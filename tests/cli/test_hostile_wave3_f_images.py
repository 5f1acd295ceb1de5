"""Wave-3 hostile sweep of the image commands (``calibrate --images``, ``simulate --images``,
``handeye-images``) and their Python API: each case exited 1, hung, printed a C library's
noise or ran silently before its fix.

The contract (tests/cli/test_hostile_issue28.py): exit 2 with one line naming the file or
option and the reason, or exit 0 with the image rejected and its reason; the Python API
raises `kinecal.InputError` (or `TypeError` for a wrong argument type).
"""

from __future__ import annotations

import json
import re
import shutil
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

import kinecal
from kinecal.cli import main

cv2 = pytest.importorskip("cv2")

_WARNING = re.compile(r"^kinecal: warning: .+ \[([a-z-]+)\]$")
BOARD = "chessboard:9x6:20"


def run(argv: list, cap) -> tuple[int, str, list[str]]:
    """Exit status, stdout and the error lines; nothing else may be on stderr."""
    code = main([str(a) for a in argv])
    out, err = cap.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("kinecal: error: ")]
    other = [line for line in lines if line not in errors and not _WARNING.match(line)
             and not line.startswith("wrote ")]
    assert not other, err
    return code, out, errors


def png_header(path: Path, width: int, height: int) -> None:
    """A valid 1-bit PNG of any size (50 kB for 20000 x 20000)."""
    row = b"\x00" + bytes((width + 7) // 8)
    co = zlib.compressobj(9)
    data = b"".join(co.compress(row) for _ in range(height)) + co.flush()

    def chunk(tag: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + tag + body
                + struct.pack(">I", zlib.crc32(tag + body)))

    path.write_bytes(b"\x89PNG\r\n\x1a\n"
                     + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0))
                     + chunk(b"IDAT", data) + chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    from kinecal.vision.boards import parse_board
    from kinecal.vision.render import render_handeye_scene, write_scene

    K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
    sc = render_handeye_scene(parse_board(BOARD), K, np.zeros(5), (480, 360), 6, seed=5)
    return write_scene(sc, tmp_path_factory.mktemp("scene"))


@pytest.fixture
def scene(rendered, tmp_path):
    """A private copy of the rendered hand-eye scene."""
    return Path(shutil.copytree(rendered, tmp_path / "scene"))


def handeye(scene: Path) -> list:
    return ["handeye-images", scene / "images", scene / "robot_poses.csv", "--board", BOARD,
            "--intrinsics", scene / "camera.yaml", "--json"]


def rejected(out: str) -> dict[str, str]:
    return {r["image"]: r["reason"] for r in json.loads(out)["rejected"]}


# ------------------------------------------------------------------ image files
def test_an_odd_sized_image_is_rejected_without_decoding_it(scene, capsys, monkeypatch):
    odd = scene / "images" / "station_003.png"
    cv2.imwrite(str(odd), cv2.resize(cv2.imread(str(odd)), (640, 480)))
    decoded = []
    imread = cv2.imread
    monkeypatch.setattr(cv2, "imread", lambda path, *a: decoded.append(Path(path).name)
                        or imread(path, *a))
    code, out, _ = run(handeye(scene), capsys)
    assert code == 0
    assert rejected(out)["station_003.png"] == ("image size 640x480 differs from the other "
                                                "images' 480x360")
    # before: decoded (a 9000 x 9000 one took 51 s) and only then rejected
    assert "station_003.png" not in decoded and "station_002.png" in decoded


@pytest.mark.parametrize("kind", ["png", "jpeg"])
def test_a_truncated_image_file_is_rejected_as_truncated_without_library_noise(scene, capfd,
                                                                               kind):
    p = scene / "images" / "station_002.png"
    data = p.read_bytes() if kind == "png" else \
        cv2.imencode(".jpg", cv2.imread(str(p)))[1].tobytes()
    p.write_bytes(data[: len(data) // 2])
    # before: libpng / libjpeg printed on stderr (run() refuses any other line), and the
    # JPEG was decoded in part, its lower half grey
    code, out, _ = run(handeye(scene), capfd)
    assert code == 0
    assert rejected(out)["station_002.png"].startswith("truncated or corrupt image file")


@pytest.mark.parametrize("shape", [(1, 1), (9, 9), (1, 100000), (2, 1000)])
def test_an_image_too_small_for_a_board_is_rejected_not_an_opencv_assertion(shape):
    from kinecal.vision.boards import parse_board
    from kinecal.vision.detect import detect

    det = detect(np.full(shape, 128, np.uint8), parse_board(BOARD))  # before: cv2.error
    assert not det.ok and "too small to show a board" in det.reason


def test_a_16_bit_image_array_is_scaled_as_opencv_reads_16_bit_files(rendered):
    from kinecal.vision.boards import parse_board
    from kinecal.vision.detect import detect

    gray = cv2.imread(str(rendered / "images" / "station_000.png"), cv2.IMREAD_GRAYSCALE)
    board = parse_board(BOARD)
    a, b = detect(gray, board), detect(gray.astype(np.uint16) * 257, board)
    assert a.ok and b.ok  # before: clipped at 255, a white image
    np.testing.assert_array_equal(a.corners, b.corners)


# ------------------------------------------------------------------ board specs
@pytest.mark.parametrize("spec", ["chessboard:3000x3000:25", "chessboard:2x2:25",
                                  "charuco:1000x1000:40:30:DICT_ARUCO_ORIGINAL",
                                  "circles:100000x100000:20"])
def test_impossible_board_specs_are_refused_when_parsed(spec):
    from kinecal.vision.boards import parse_board

    # before: accepted, then MemoryError (petabytes), a hang or an OpenCV assertion
    with pytest.raises(kinecal.InputError) as exc:
        parse_board(spec)
    assert exc.value.option == "--board"


# ------------------------------------------------------------------ intrinsics
GOOD = ("image_width: 480\nimage_height: 360\ncamera_matrix: {rows: 3, cols: 3, data: "
        "[700, 0, 239.5, 0, 700, 179.5, 0, 0, 1]}\ndistortion_model: plumb_bob\n"
        "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n")
INTRINSICS = [
    ("cam.json", "[" * 100000 + "]" * 100000, "nested too deeply"),
    ("cam.json", '{"camera_matrix": [[9' + "9" * 5000 + ", 0, 1], [0, 1, 1], [0, 0, 1]]}",
     "thousands of digits"),
    ("cam.xml", "<?xml version='1.0'?><opencv_storage><K>", "OpenCV FileStorage"),
    ("cam.yaml", "%YAML:1.0\ncamera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
     "  data: [1, 2]\n", "OpenCV FileStorage"),
    ("cam.yaml", GOOD.replace("plumb_bob", "banana"), "unknown distortion_model 'banana'"),
    ("cam.yaml", GOOD.replace("image_width: 480", "image_width: -480"), "image_width"),
    ("cam.yaml", GOOD.replace("480", "100000").replace("360", "100000"), "image_width"),
]


@pytest.mark.parametrize(("name", "text", "expected"), INTRINSICS)
def test_broken_intrinsics_files_are_refused_with_the_file_named(tmp_path, name, text,
                                                                 expected):
    from kinecal.vision.intrinsics import read_intrinsics

    p = tmp_path / name
    p.write_text(text)
    # before: RecursionError, ValueError, SystemError, cv2.error, or accepted
    with pytest.raises(kinecal.InputError) as exc:
        read_intrinsics(p)
    assert expected in exc.value.message and Path(exc.value.file) == p


# ------------------------------------------------------------------ options
def test_a_board_contact_beyond_any_length_is_refused():
    from kinecal.calibration.handeye.scara import AxisHeight
    from kinecal.cli.handeye import parse_contact

    with pytest.raises(kinecal.InputError, match="within"):
        parse_contact("1e308,0,0")  # before: exit 1 LinAlgError
    with pytest.raises(kinecal.InputError, match="three finite"):
        AxisHeight.from_options(None, "abc")  # before: ValueError


@pytest.mark.parametrize(("option", "value"), [("--noise", "1e308"), ("--blur", "1e308")])
def test_simulate_images_refuses_noise_and_blur_beyond_an_image(tmp_path, capsys, option,
                                                                value):
    code, _, errors = run(["simulate", "kr6-craig", "--images", tmp_path / "img", "--board",
                           BOARD, "--poses", "3", "--out", tmp_path / "s.csv", option, value],
                          capsys)
    assert code == 2 and option in errors[0]  # before: exit 1 (OverflowError, cv2.error)
    assert not (tmp_path / "s.csv").exists() and not (tmp_path / "img").exists()


def test_validation_stations_must_be_held_out(scene, capsys):
    rows = ["image,q1,q2,q3,q4,q5,q6"] + [f"{p.name},0,10,20,0,30,0"
                                          for p in sorted((scene / "images").glob("*.png"))]
    (scene / "stations.csv").write_text("\n".join(rows) + "\n")
    code, _, errors = run(["calibrate", "kr6-craig", scene / "stations.csv", "--images",
                           scene / "images", "--board", BOARD, "--validate",
                           scene / "stations.csv", "--out", scene / "r.json"], capsys)
    assert code == 2 and "must be held out" in errors[0]  # before: a silent "validation"
    assert not (scene / "r.json").exists()


# ------------------------------------------------------------------ Python API
def test_the_image_pipelines_python_api_refuses_bad_arguments(rendered):
    from kinecal.io.handeye import read_robot_poses
    from kinecal.vision.boards import parse_board

    names, F = read_robot_poses(rendered / "robot_poses.csv")
    images = [rendered / "images" / n for n in names]
    board, model = parse_board(BOARD), kinecal.load_model("kr6-craig")
    q = np.zeros((len(images), 6))
    he, arm = kinecal.calibrate_handeye_images, kinecal.calibrate_arm_images  # before: absent
    with pytest.raises(kinecal.InputError, match="one name per image"):
        he(images, F, board, names=names[:2])  # before: ValueError from zip
    with pytest.raises(TypeError, match="board: expected a Board"):
        he(images, F, BOARD)  # before: AttributeError
    with pytest.raises(TypeError, match="intrinsics: expected CameraIntrinsics"):
        he(images, F, board, intrinsics={"K": 1})
    with pytest.raises(kinecal.InputError, match="expected numbers"):
        arm(model, images, [["a"] * 6] * len(images), board)  # before: ValueError
    with pytest.raises(TypeError, match="model: expected a SerialModel"):
        arm("kr6-craig", images, q, board)
    with pytest.raises(kinecal.InputError, match="validate q"):
        arm(model, images, q, board, validate=(images[:2], q[:3], names[:2]))  # before: ran
