"""Image files sized from their header before anything decodes them.

A PNG of 20000 x 20000 pixels is 50 kB on disk and 400 MB once decoded; among board images
it made ``kinecal handeye-images`` run for minutes and end in a `MemoryError`. Every image
file is therefore sized first from its header alone (Pillow parses only the PNG ``IHDR``,
the JPEG ``SOF`` marker, the TIFF / BMP / PNM headers: no pixel is decoded), and one with
more pixels than `MAX_IMAGE_PIXELS`, or than this machine's memory can detect a board in, is
rejected with its size. Files Pillow does not recognise go on to OpenCV, which keeps its own
limit (``OPENCV_IO_MAX_IMAGE_PIXELS``, 2^30 pixels by default).

`check_image_file` also refuses a file that ends early (a copy cut short, a card pulled out
while writing): a PNG's chunks are walked and checked without inflating them, a JPEG's
entropy-coded data is decoded at 1/8 scale (in the DCT domain, a few milliseconds). OpenCV
would decode such files in part, print libpng's or libjpeg's complaint on stderr and, for a
JPEG, hand back an image whose lower part is grey.

A PNG of the plain layout that OpenCV and most camera tools write (``IHDR``, then ``IDAT``
chunks, optional chunks after the first ``IDAT``, ``IEND``) is sized and checked here
without Pillow (`_plain_png_size`: every chunk's CRC, as Pillow's ``verify``; 0.3 instead
of 1.1 ms an image, and no Pillow import at start-up); any other file, or a PNG with
anything unusual (a bad CRC, a chunk cut short, ancillary chunks before the image data),
goes through Pillow as before, which gives the verdict and its message.
"""

from __future__ import annotations

import re
import struct
import warnings
import zlib
from pathlib import Path

from kinecal._limits import available_memory
from kinecal.errors import InputError

__all__ = ["DETECT_BYTES_PER_PIXEL", "MAX_IMAGE_PIXELS", "check_image_file", "check_image_size",
           "header_size"]

#: largest image accepted, in pixels (2^27, 134 MP): beyond the 100-130 MP of the largest
#: medium-format and machine-vision sensors; a board is found in far fewer pixels
MAX_IMAGE_PIXELS = 1 << 27
#: peak memory of board detection per pixel of a grey image (measured: 7.2 GB for 4e8
#: pixels, 18 bytes; with a margin)
DETECT_BYTES_PER_PIXEL = 24


def header_size(path: str | Path) -> tuple[int, int] | None:
    """``(width, height)`` of an image file from its header (nothing decoded).

    Returns None when Pillow does not recognise the file (OpenCV may still read it).

    Raises
    ------
    InputError
        An image beyond Pillow's decompression-bomb limit (about 1.8e8 pixels).
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                return int(im.width), int(im.height)
    except Image.DecompressionBombError as exc:
        found = re.search(r"\((\d+) pixels\)", str(exc))  # Pillow says how many
        pixels = (f"{int(found[1]) / 1e6:.0f} MP" if found else
                  f"more than {2 * Image.MAX_IMAGE_PIXELS / 1e6:.0f} MP")
        raise InputError(f"{pixels} in its header, more than the {MAX_IMAGE_PIXELS / 1e6:.0f} "
                         "MP a camera image may have (never decoded)", file=path) from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
        return None


def check_image_size(path: str | Path) -> tuple[int, int] | None:
    """The header size of an image file, refused when too large to be a camera's.

    Raises
    ------
    InputError
        More pixels than `MAX_IMAGE_PIXELS`, or than the memory available for detection
        (`DETECT_BYTES_PER_PIXEL` per pixel).
    """
    size = header_size(path)
    return None if size is None else _refuse_too_large(path, *size)


def _refuse_too_large(path: str | Path, w: int, h: int) -> tuple[int, int]:
    most = min(MAX_IMAGE_PIXELS, available_memory() // DETECT_BYTES_PER_PIXEL)
    if w * h > most:
        raise InputError(f"{w}x{h} pixels ({w * h / 1e6:.0f} MP) in its header, more than the "
                         f"{most / 1e6:.0f} MP a camera image may have here (never decoded)",
                         file=path)
    return w, h


def check_image_file(path: str | Path) -> tuple[int, int] | None:
    """`check_image_size`, and a PNG or JPEG file that ends early refused.

    Returns
    -------
    (int, int) or None
        Width and height from the header; None when Pillow does not recognise the file.

    Raises
    ------
    InputError
        Too large (`check_image_size`), or a PNG / JPEG that is truncated or corrupt.
    """
    plain = _plain_png_size(path)
    if plain is not None:
        return _refuse_too_large(path, *plain)
    return _check_with_pillow(path)


def _check_with_pillow(path: str | Path) -> tuple[int, int] | None:
    """`check_image_file` by Pillow (any format it knows)."""
    size = check_image_size(path)
    if size is None:
        return None
    from PIL import Image, ImageFile

    # WeasyPrint (the PDF reports) sets Pillow's LOAD_TRUNCATED_IMAGES for its whole
    # process at import: after a PDF report in the same process, a truncated JPEG loaded
    # without error and its grey lower half reached the detector
    lenient, ImageFile.LOAD_TRUNCATED_IMAGES = ImageFile.LOAD_TRUNCATED_IMAGES, False
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                if im.format == "PNG":
                    im.verify()  # every chunk and its CRC, nothing inflated
                elif im.format in ("JPEG", "MPO"):
                    im.draft("L", (max(size[0] // 8, 1), max(size[1] // 8, 1)))
                    im.load()
    except (OSError, ValueError, SyntaxError, EOFError) as exc:
        raise InputError(f"truncated or corrupt image file ({' '.join(str(exc).split())})",
                         file=path) from None
    finally:
        ImageFile.LOAD_TRUNCATED_IMAGES = lenient
    return size


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: (bit depth, colour type) pairs of the PNG standard (all of which Pillow reads)
_PNG_MODES = {(1, 0), (2, 0), (4, 0), (8, 0), (16, 0), (8, 2), (16, 2), (1, 3), (2, 3),
              (4, 3), (8, 3), (8, 4), (16, 4), (8, 6), (16, 6)}
#: Pillow's decompression-bomb error threshold (twice its default MAX_IMAGE_PIXELS): beyond
#: it Pillow's own message is the one given
_PILLOW_BOMB = 2 * (1024 * 1024 * 1024 // 4 // 3)
_CHUNK_TYPE = re.compile(rb"\w\w\w\w")


def _plain_png_size(path: str | Path) -> tuple[int, int] | None:
    """``(width, height)`` of a PNG file of the plain layout whose every chunk is whole and
    matches its CRC (what Pillow's ``verify`` accepts, with the same size); None for any
    other file, which Pillow then judges."""
    try:
        with open(path, "rb") as f:
            if f.read(8) != _PNG_SIGNATURE:
                return None
            data = f.read()
    except OSError:
        return None
    end = len(data)
    if end < 25 or data[4:8] != b"IHDR" or struct.unpack_from(">I", data, 0)[0] != 13:
        return None
    w, h, depth, colour, _, filt, _ = struct.unpack_from(">IIBBBBB", data, 8)
    if (depth, colour) not in _PNG_MODES or filt != 0 or not 0 < w * h <= _PILLOW_BOMB:
        return None
    pos, seen_data = 0, False
    while True:
        if pos + 8 > end:
            return None  # cut short
        length = struct.unpack_from(">I", data, pos)[0]
        kind = data[pos + 4:pos + 8]
        if not _CHUNK_TYPE.fullmatch(kind):
            return None
        if kind == b"IEND":
            return (w, h) if seen_data else None
        if kind == b"IDAT":
            seen_data = True
        elif pos and not seen_data:
            return None  # ancillary chunks before the image data: Pillow parses them
        stop = pos + 8 + length
        if stop + 4 > end or zlib.crc32(memoryview(data)[pos + 4:stop]) != \
                struct.unpack_from(">I", data, stop)[0]:
            return None
        pos = stop + 4
