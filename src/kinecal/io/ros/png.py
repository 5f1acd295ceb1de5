"""PNG files from raw image buffers (numpy and zlib; no imaging library).

A PNG (ISO/IEC 15948) is the 8-byte signature and three chunks: ``IHDR`` (size, bit depth,
colour type), ``IDAT`` (the zlib stream of the rows, each prefixed by filter type 0) and
``IEND``; each chunk is its length, type, data and the CRC-32 of type and data.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np
from numpy.typing import NDArray

__all__ = ["encode_png"]

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: PNG colour type per number of channels: grey, grey + alpha, RGB, RGBA
_COLOUR = {1: 0, 2: 4, 3: 2, 4: 6}


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def encode_png(pixels: NDArray, level: int = 1) -> bytes:
    """The PNG bytes of an image ``(H, W)`` or ``(H, W, C)`` (C = 1..4), uint8 or uint16.

    Channels are written in the order given (grey; grey, alpha; R, G, B; R, G, B, A).
    `level` is zlib's compression level (1: fast).
    """
    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in _COLOUR or a.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"expected (H, W[, 1..4]) uint8 or uint16, got {a.shape} {a.dtype}")
    h, w, c = a.shape
    depth = 8 if a.dtype == np.uint8 else 16
    rows = np.ascontiguousarray(a.astype(">u2") if depth == 16 else a).reshape(h, -1)
    data = rows.view(np.uint8).reshape(h, -1)  # bytes: two per sample at depth 16
    raw = np.zeros((h, data.shape[1] + 1), dtype=np.uint8)  # filter byte 0 per row
    raw[:, 1:] = data
    header = struct.pack(">IIBBBBB", w, h, depth, _COLOUR[c], 0, 0, 0)
    return (_SIGNATURE + _chunk(b"IHDR", header)
            + _chunk(b"IDAT", zlib.compress(raw.tobytes(), level)) + _chunk(b"IEND", b""))
