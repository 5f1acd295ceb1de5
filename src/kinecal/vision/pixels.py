"""Pixel statistics and filters of board detection, computed where they are needed and
exactly as on the whole image.

Board detection (`kinecal.vision.detect`) smooths the image before the sub-pixel corner
search and measures the edge width from grey-level percentiles; done on the whole image,
these cost several times the OpenCV detector itself. Here they are computed on less data
with the same results, bit for bit (tests/vision):

- `percentiles_of_levels`: `numpy.percentile` (linear method) of 8-bit grey levels from
  their histogram (order statistics from the cumulative counts);
- `upper_percentile`: a high percentile of a float32 vector from the values above a
  threshold taken from a subsample;
- `blurred_around`: the Gaussian-smoothed image within reach of some points, blurred on
  that box plus the kernel's radius only;
- `hull_polygon`: the grown convex hull of the corners, in integer pixels.
"""

from __future__ import annotations

import threading

import numpy as np
from numpy.typing import NDArray

from kinecal.vision import require_cv2

Array = NDArray[np.float64]

__all__ = ["blurred_around", "hull_polygon", "percentiles_of_levels", "upper_percentile"]


def upper_percentile(x: NDArray[np.float32], q: float) -> float:
    """``float(numpy.percentile(x, q))`` (linear method, scalar `q` near 100) for a float32
    vector, selecting the two order statistics among the values above a threshold taken
    from a subsample (a few hundred values instead of a partition of all); the same value,
    bit for bit (tests/vision), numpy's own call when the threshold is not low enough."""
    n = x.size
    vi = (n - 1) * np.true_divide(q, 100)
    k0 = int(np.floor(vi))
    k1 = min(k0 + 1, n - 1)
    if n < 4096 or vi >= n - 1:
        return float(np.percentile(x, q))
    sub = x[::16]
    j = int(0.99 * (q / 100) * (sub.size - 1))  # a little below the quantile sought
    t = np.partition(sub, j)[j]
    cand = x[x >= t]
    below = n - cand.size  # values under t: the ranks k0, k1 must lie above them
    if below > k0:
        return float(np.percentile(x, q))
    cand.sort()
    a, b = cand[k0 - below], cand[k1 - below]
    gamma = float(vi - np.floor(vi))
    diff = b - a  # float32, as numpy's interpolation with a scalar q
    return float(b - diff * (1 - gamma) if gamma >= 0.5 else a + diff * gamma)


def percentiles_of_levels(counts: Array, q: tuple[float, ...]) -> Array:
    """``numpy.percentile`` (linear method) of integer levels given by their histogram
    ``counts`` (level i counted ``counts[i]`` times): the order statistics from the
    cumulative counts, interpolated exactly as numpy does (same values, bit for bit;
    tests/vision)."""
    cum = np.cumsum(counts.astype(np.int64))
    n = int(cum[-1])
    vi = (n - 1) * np.true_divide(np.asarray(q, dtype=float), 100)
    prev = np.floor(vi)
    i0 = np.clip(prev, 0, n - 1).astype(np.intp)
    i1 = np.clip(prev + 1, 0, n - 1).astype(np.intp)
    a = np.searchsorted(cum, i0, side="right").astype(float)  # level of rank i0
    b = np.searchsorted(cum, i1, side="right").astype(float)
    gamma = vi - prev
    diff = b - a
    return np.where(gamma >= 0.5, b - diff * (1 - gamma), a + diff * gamma)


def hull_polygon(pts: Array, grow: float) -> NDArray[np.int32]:
    """Integer vertices ``(k, 2)`` of the convex hull of `pts` grown about its centroid."""
    cv2 = require_cv2()
    hull = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2)
    c = hull.mean(axis=0)
    hull = c + (hull - c) * grow
    return np.round(hull).astype(np.int32)


def blurred_around(gray: NDArray[np.uint8], pts: Array, sigma: float,
                    reach: int) -> NDArray[np.float32]:
    """The image smoothed by a Gaussian of `sigma`, computed only where it is read: within
    `reach` px of `pts` (elsewhere zero). The blur runs on that box plus the kernel's
    radius, so every pixel within reach has exactly the value the whole image's blur gives
    (the box edge is the image border, or farther than the kernel reaches)."""
    cv2 = require_cv2()
    h, w = gray.shape
    margin = reach + int(np.ceil(4.0 * sigma)) + 2  # OpenCV's float kernel: 4 sigma radius
    x0, y0 = np.maximum(np.floor(pts.min(axis=0)).astype(int) - margin, 0)
    x1, y1 = np.minimum(np.ceil(pts.max(axis=0)).astype(int) + margin + 1, (w, h))
    out = _zeroed_image((h, w))
    out[y0:y1, x0:x1] = cv2.GaussianBlur(gray[y0:y1, x0:x1].astype(np.float32), (0, 0), sigma)
    return out


_SCRATCH = threading.local()


def _zeroed_image(shape: tuple[int, int]) -> NDArray[np.float32]:
    """A zeroed float32 image, this thread's buffer reused (a fresh megabyte-sized array
    costs more in page faults than the blur that fills it). Valid until the thread's next
    call."""
    buf = getattr(_SCRATCH, "image", None)
    if buf is None or buf.shape != shape:
        buf = np.zeros(shape, np.float32)
        _SCRATCH.image = buf
    else:
        buf.fill(0.0)
    return buf
