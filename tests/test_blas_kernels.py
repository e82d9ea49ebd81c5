"""One evaluation of the regularizer under several OpenBLAS kernels agrees to rounding.

OpenBLAS picks its kernel (Haswell, SkylakeX, ...) from the CPU, or from ``OPENBLAS_CORETYPE``; kernels
sum in different orders and with or without FMA, so the same call returns different last bits. The
suite never sets the variable for itself: this test sets it in subprocesses only, and checks that
the differences stay within the backward-error bounds the other tests use between two eigensolvers
(tests/test_regularizer.py). docs/REPRODUCTION.md#across-blas-kernels measures the effect on the tables.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

EPS = np.finfo(float).eps
N, RHO = 120, 10.0

SCRIPT = f"""
import json
import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits
from nldr.data_terms import MaskedLeastSquares
from nldr.kernels import rbf_kernel
from nldr.regularizer import reduced_energy

rng = np.random.default_rng(0)
X = rng.standard_normal(({N}, 5))
mask = rng.random(X.shape) > 0.3
S = X + 0.1 * rng.standard_normal(X.shape)
term = MaskedLeastSquares(X, mask)
with threadpool_limits(1):
    value, grad = reduced_energy(S, term, gamma=0.5, tau=0.1, rho={RHO}, eigensolver="full")
    K = rbf_kernel(S, 0.5)
    blas = [i for i in threadpool_info() if i["internal_api"] == "openblas"]
    out = {{
        "arch": sorted({{i.get("architecture") for i in blas}}),
        "value": float(value).hex(),
        "grad": [float(x).hex() for x in grad.ravel()],
        "ls": float(term.value(S)).hex(),
        "n_observed": int(mask.sum()),
        "K_fro": float(np.linalg.norm(K)),
    }}
print(json.dumps(out))
"""


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    line = next((x for x in text.splitlines() if x.startswith("flags")), "")
    return set(line.split(":", 1)[-1].split())


def _run(coretype: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    if coretype is not None:
        env["OPENBLAS_CORETYPE"] = coretype
    proc = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["value"], out["ls"] = float.fromhex(out["value"]), float.fromhex(out["ls"])
    out["grad"] = np.array([float.fromhex(x) for x in out["grad"]])
    return out


def test_regularizer_energy_and_gradient_agree_to_rounding_across_openblas_kernels():
    if platform.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("OPENBLAS_CORETYPE names x86-64 kernels")
    # the machine's own choice (or the caller's OPENBLAS_CORETYPE), SSE4.2 without FMA, and AVX2 + FMA
    runs = [_run(os.environ.get("OPENBLAS_CORETYPE")), _run("Nehalem")]
    if {"avx2", "fma"} <= _cpu_flags():
        runs.append(_run("Haswell"))
    if not runs[0]["arch"]:
        pytest.skip("numpy does not use OpenBLAS here")
    assert len({tuple(r["arch"]) for r in runs}) >= 2, [r["arch"] for r in runs]  # two kernels at least
    ref = runs[0]
    # Entries of dE/dK = rho (K - C^T C) move by about rho n eps ||K||_F when K's eigenpairs carry a
    # backward error n eps ||K|| (as between two eigensolvers); the value moves by at most that times
    # ||K||_F, and the data term (a sum of n_observed squares) by n_observed eps times itself.
    grad_tol = RHO * N * EPS * ref["K_fro"]
    value_tol = grad_tol * ref["K_fro"] + ref["n_observed"] * EPS * ref["ls"]
    for other in runs[1:]:
        assert abs(other["ls"] - ref["ls"]) <= ref["n_observed"] * EPS * ref["ls"], other["arch"]
        assert abs(other["value"] - ref["value"]) <= value_tol, other["arch"]
        np.testing.assert_allclose(
            other["grad"], ref["grad"], rtol=0, atol=grad_tol, err_msg=str(other["arch"])
        )
