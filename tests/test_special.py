"""`kinecal._special.chdtri` without scipy for whole degrees of freedom: scipy's values
across the degrees of freedom and tails the outlier bounds use, and beyond."""

import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.special import chdtri as scipy_chdtri

from kinecal._special import chdtri

PROBABILITIES = [1e-300, 1e-100, 1e-12, 1e-6, 1e-3, 0.05, 0.3, 0.5, 0.7, 0.95, 0.999,
                 1 - 1e-9]


@pytest.mark.parametrize("v", [*range(1, 40), 99, 100, 101, 108, 500, 501, 1000, 1001])
def test_whole_degrees_of_freedom_match_scipy(v):
    ours = np.array([chdtri(v, p) for p in PROBABILITIES])
    ref = scipy_chdtri(v, PROBABILITIES)
    assert np.all(np.abs(ours - ref) <= 5e-14 * ref), np.max(np.abs(ours / ref - 1))


@pytest.mark.parametrize("v", [1, 2, 3, 5, 6, 8, 13, 21, 34, 55, 89, 144, 233, 377, 610, 987])
def test_grid_matches_scipy_stats_chi2(v):
    """The quantile against `scipy.stats.chi2` over a grid of lower-tail probabilities
    (``chdtri(v, 1 - q)`` is ``chi2.ppf(q, v)``) and of upper-tail ones (``chi2.isf``)."""
    from scipy.stats import chi2

    q = np.array([0.001, 0.01, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99, 0.999])
    ours = np.array([chdtri(v, 1.0 - qi) for qi in q])
    assert np.allclose(ours, chi2.ppf(q, v), rtol=5e-14, atol=0)
    p = np.geomspace(1e-200, 0.5, 25)
    ours = np.array([chdtri(v, pi) for pi in p])
    assert np.allclose(ours, chi2.isf(p, v), rtol=5e-14, atol=0)


def test_closed_forms_and_shapes():
    # 2 dof: Q(x) = exp(-x/2), so x = -2 log p exactly
    for p in (1e-3, 0.25, 0.9):
        assert chdtri(2, p) == pytest.approx(-2 * np.log(p), rel=1e-15)
    # 1 dof: the square of the normal quantile (1.959963984540054 at p = 0.05)
    assert chdtri(1, 0.05) == pytest.approx(1.959963984540054**2, rel=1e-14)
    got = chdtri(np.array([[6, 108], [6, 3]]), 1e-3)
    assert got.shape == (2, 2) and got[0, 0] == got[1, 0]
    assert np.allclose(got, scipy_chdtri(np.array([[6, 108], [6, 3]]), 1e-3), rtol=5e-14)
    assert isinstance(chdtri(6, 1e-3), np.floating)
    # not whole, or a probability of 0 or 1: scipy's answer
    assert chdtri(2.5, 0.3) == scipy_chdtri(2.5, 0.3)
    assert chdtri(4, 1.0) == scipy_chdtri(4, 1.0) == 0.0


def test_whole_dof_quantile_imports_no_scipy():
    code = ("import sys\nfrom kinecal._special import chdtri\nchdtri(6, 1e-3)\n"
            "chdtri([108, 3], [1e-3, 0.5])\nassert 'scipy' not in sys.modules")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    subprocess.run([sys.executable, "-c", code], check=True, env=env)
