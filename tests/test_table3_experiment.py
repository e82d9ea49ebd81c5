"""Table 3's experiment runner: parallel width criteria give the serial results."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from nldr.datasets import load_mocap
from nldr.experiments._table3 import run_sequence


def test_width_criteria_in_worker_processes_reproduce_the_serial_run(data_dir):
    seq = load_mocap("pickup", data_dir).subsample(10)
    kw = dict(missing_fraction=0.5, seed=2016, tnh_options={"solver": "ADMM"})
    with threadpool_limits(1):  # the workers use one BLAS thread: same arithmetic in both runs
        serial = run_sequence(seq, **kw)
    parallel = run_sequence(seq, n_jobs=2, **kw)
    assert list(parallel.rows["method"]) == ["TNH", "Kernel d_max", "Kernel d_med"]
    np.testing.assert_allclose(parallel.rows["e3d"], serial.rows["e3d"], rtol=1e-12)
    for label, X in serial.shapes.items():
        np.testing.assert_allclose(parallel.shapes[label], X, rtol=0, atol=1e-12 * np.abs(X).max())
    # each kernel solve improves on TNH, as in Table 3
    assert (parallel.rows["e3d"].iloc[1:] < parallel.rows["e3d"].iloc[0]).all()


@pytest.mark.parametrize("n_jobs", [0, 1.5, True])
def test_bad_n_jobs_is_rejected(data_dir, n_jobs):
    seq = load_mocap("pickup", data_dir).subsample(10)
    with pytest.raises(ValueError, match="n_jobs"):
        run_sequence(seq, missing_fraction=0.0, seed=0, n_jobs=n_jobs)


def test_stage_tolerances_reach_the_solver_and_are_validated(data_dir):
    """L-BFGS's ftol test is (E_k - E_k+1) / max(|E_k|, |E_k+1|, 1) <= tol, true after the first
    iteration whenever tol >= 1 (an energy decrease never exceeds max(|E|, 1) for E >= 0): with
    tol = 1 every penalty stage stops after one iteration, which the default tolerance does not."""
    seq = load_mocap("pickup", data_dir).subsample(10)
    kw = dict(missing_fraction=0.0, seed=0, widths=("d_med",))
    schedule = dict(rho0=1e-3, rho_max=1e-1)
    loose = run_sequence(seq, regularizer={**schedule, "tol": 1.0}, **kw).results["Kernel d_med"]
    assert loose.nit == loose.n_stages == 3
    default = run_sequence(seq, regularizer=schedule, **kw).results["Kernel d_med"]
    assert default.nit > 10 * default.n_stages
    for key in ("tol", "gtol", "stage_tol"):
        with pytest.raises(ValueError, match=key):
            run_sequence(seq, regularizer={**schedule, key: -1.0}, **kw)
