"""Test-suite settings shared by every test module."""

import os

# Small matrices everywhere: single-threaded BLAS avoids oversubscribing CI's 2 cores.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
