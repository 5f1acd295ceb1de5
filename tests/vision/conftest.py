"""Shared camera of the vision tests (small images keep the suite fast)."""

from __future__ import annotations

import numpy as np
import pytest

K = np.array([[700.0, 0.0, 239.5], [0.0, 700.0, 179.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.12, 0.04, 0.0005, -0.0003, 0.0])
SIZE = (480, 360)


@pytest.fixture
def camera():
    """(K, dist, size) of a 480 x 360 camera with moderate barrel distortion."""
    return K.copy(), DIST.copy(), SIZE
