"""PNG files sized and checked without Pillow (`image_files._plain_png_size`) get Pillow's
verdict: the same size, or the same refusal and message, on clean, cut, corrupted,
decorated and oversized files."""

import struct
import zlib

import cv2
import numpy as np

from kinecal.errors import InputError
from kinecal.vision.image_files import _check_with_pillow, _plain_png_size, check_image_file


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _chunks(png: bytes) -> list[tuple[bytes, bytes]]:
    out, pos = [], 8
    while pos < len(png):
        n = struct.unpack_from(">I", png, pos)[0]
        out.append((png[pos + 4:pos + 8], png[pos + 8:pos + 8 + n]))
        pos += 12 + n
    return out


def _assemble(chunks) -> bytes:
    return b"\x89PNG\r\n\x1a\n" + b"".join(_chunk(k, d) for k, d in chunks)


def _verdict(fn, path):
    try:
        return ("size", fn(path))
    except InputError as exc:
        return ("refused", exc.message)


def _files(tmp_path):
    rng = np.random.default_rng(4)
    gray = rng.integers(0, 256, (60, 80), dtype=np.uint8)
    clean = cv2.imencode(".png", gray)[1].tobytes()
    colour = cv2.imencode(".png", rng.integers(0, 256, (30, 40, 3), dtype=np.uint8))[1].tobytes()
    deep = cv2.imencode(".png", rng.integers(0, 65536, (30, 40), dtype=np.uint16))[1].tobytes()
    parts = _chunks(clean)
    text = (b"tEXt", b"Comment\x00kinecal")
    ihdr = parts[0][1]
    files = {
        "clean": (clean, True), "colour": (colour, True), "16-bit": (deep, True),
        "text after the image data": (_assemble([*parts[:-1], text, parts[-1]]), True),
        "data after IEND": (clean + b"trailing bytes", True),
        "text before the image data": (_assemble([parts[0], text, *parts[1:]]), False),
        "bad CRC in the image data": (clean[:60] + bytes([clean[60] ^ 1]) + clean[61:], False),
        "bad CRC in IHDR": (clean[:20] + bytes([clean[20] ^ 4]) + clean[21:], False),
        "no IEND": (_assemble(parts[:-1]), False),
        "bad chunk name": (_assemble([*parts[:-1], (b"t-Xt", b"x"), parts[-1]]), False),
        "filter method 1": (_assemble([(b"IHDR", ihdr[:11] + b"\x01" + ihdr[12:]),
                                       *parts[1:]]), False),
        "colour type 5": (_assemble([(b"IHDR", ihdr[:9] + b"\x05" + ihdr[10:]),
                                     *parts[1:]]), False),
    }
    for w, h in ((12000, 12000), (15000, 15000), (0, 10)):  # refused here / by Pillow
        big = struct.pack(">II", w, h) + ihdr[8:]
        files[f"{w}x{h} header"] = (_assemble([(b"IHDR", big), *parts[1:]]),
                                    w == 12000)
    for cut in (9, 20, 33, 37, 45, len(clean) // 2, len(clean) - 13, len(clean) - 12,
                len(clean) - 5, len(clean) - 4, len(clean) - 1):
        files[f"cut at {cut}"] = (clean[:cut], cut >= len(clean) - 4)
    out = []
    for name, (data, plain) in files.items():
        p = tmp_path / (name.replace(" ", "_") + ".png")
        p.write_bytes(data)
        out.append((name, p, plain))
    return out


def test_plain_pngs_get_pillows_verdict(tmp_path):
    taken = 0
    for name, path, plain in _files(tmp_path):
        assert (_plain_png_size(path) is not None) == plain, name
        taken += plain
        assert _verdict(check_image_file, path) == _verdict(_check_with_pillow, path), name
    assert taken >= 6


def test_not_png_goes_to_pillow(tmp_path):
    p = tmp_path / "a.jpg"
    p.write_bytes(cv2.imencode(".jpg", np.full((40, 50), 128, np.uint8))[1].tobytes())
    assert _plain_png_size(p) is None and check_image_file(p) == (50, 40)
    assert _plain_png_size(tmp_path / "missing.png") is None
