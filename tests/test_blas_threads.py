"""kinecal's dense products run on one BLAS thread, whatever numpy's default (kinecal._blas).

Each case runs in a fresh interpreter whose BLAS libraries load with two threads (the test
suite's own process pins them to one before numpy loads).
"""

import json
import os
import subprocess
import sys

import pytest

pytest.importorskip("threadpoolctl")

#: prints the BLAS libraries' threads outside, inside the LM solver and inside calibrate(),
#: then after both
PROBE = r"""
import json
import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_info
import kinecal
from kinecal.optimize.lm import solve_normal_equations

def blas():
    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

seen = {"before": blas()}

def normal_equations(x):
    seen.setdefault("lm", blas())
    r = x - 1.0
    return r, np.eye(2), r

solve_normal_equations(normal_equations, np.zeros(2))
m = kinecal.load_model("ur5")
sim = kinecal.simulate(m, 30, errors="random", noise=0.01, rng=1)
real_gram = type(m).identification_jacobian

def spy(self, *a, **k):
    seen.setdefault("calibrate", blas())
    return real_gram(self, *a, **k)

type(m).identification_jacobian = spy
res = kinecal.calibrate(m, sim.data, free=["a2", "a3", "d4"])
seen["after"] = blas()
seen["ok"] = bool(res.success)
print(json.dumps(seen))
"""


def probe(env_extra: dict[str, str], code: str = PROBE) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                        "KINECAL_BLAS_THREADS")}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True, timeout=120)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_solvers_limit_blas_to_one_thread_and_restore_it():
    seen = probe({"OPENBLAS_NUM_THREADS": "2"})
    assert seen["before"] == [2]
    assert seen["lm"] == [1]
    assert seen["after"] == [2]  # the user's setting is back after the call
    assert seen["ok"]
    assert seen["calibrate"] == [1]  # the Jacobian is formed inside calibrate's limit


def test_kinecal_blas_threads_zero_leaves_the_libraries_alone():
    seen = probe({"OPENBLAS_NUM_THREADS": "2", "KINECAL_BLAS_THREADS": "0"})
    assert seen["before"] == seen["lm"] == seen["after"] == [2]


def test_command_line_pins_one_thread_before_numpy_loads():
    code = ("import sys\nfrom kinecal.cli import _blas\nimport numpy\n"
            "from threadpoolctl import threadpool_info\nimport json\n"
            "print(json.dumps({'pinned': _blas._started_single, 'threads': sorted({i["
            "'num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'})}))")
    seen = probe({}, code)
    assert seen == {"pinned": True, "threads": [1]}
    # an explicit user setting wins, and then the solvers limit the threads themselves
    seen = probe({"OPENBLAS_NUM_THREADS": "2"}, code)
    assert seen == {"pinned": False, "threads": [2]}


def test_two_threads_share_the_limit_and_restore_the_setting():
    """Two solver calls overlapping in two threads (the first ends while the second is
    still inside): both run on one BLAS thread throughout, and the session's two threads
    are back once both have returned."""
    code = r"""
import json, threading
import numpy as np
from threadpoolctl import threadpool_info
from kinecal.optimize.lm import solve_normal_equations

def blas():
    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

a_in, b_in, a_done = threading.Event(), threading.Event(), threading.Event()
seen = {}

def solve(name, on_first):
    first = []
    def normal_equations(x):
        if not first:
            first.append(1)
            on_first()
        seen.setdefault(name, blas())
        r = x - 1.0
        return r, np.eye(2), r
    solve_normal_equations(normal_equations, np.zeros(2))

def a():
    solve("a", lambda: (a_in.set(), b_in.wait(10)))
    a_done.set()

def b():
    a_in.wait(10)
    solve("b", lambda: (b_in.set(), a_done.wait(10)))  # a has returned: b still inside

ta, tb = threading.Thread(target=a), threading.Thread(target=b)
ta.start(); tb.start(); ta.join(); tb.join()
print(json.dumps({"a": seen["a"], "b": seen["b"], "after": blas()}))
"""
    seen = probe({"OPENBLAS_NUM_THREADS": "2"}, code)
    assert seen == {"a": [1], "b": [1], "after": [2]}
