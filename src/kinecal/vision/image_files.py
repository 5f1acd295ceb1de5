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
"""

from __future__ import annotations

import re
import warnings
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
    if size is None:
        return None
    w, h = size
    most = min(MAX_IMAGE_PIXELS, available_memory() // DETECT_BYTES_PER_PIXEL)
    if w * h > most:
        raise InputError(f"{w}x{h} pixels ({w * h / 1e6:.0f} MP) in its header, more than the "
                         f"{most / 1e6:.0f} MP a camera image may have here (never decoded)",
                         file=path)
    return size


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
