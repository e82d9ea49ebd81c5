"""Tests of minimize_regularized's progress report (``verbose``) and per-stage ``callback``."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from nldr._penalty import StageInfo
from nldr.data_terms import MaskedLeastSquares
from nldr.regularizer import minimize_regularized
from nldr.result import CONVERGED, INACCURATE

KW = dict(gamma=0.5, tau=0.1, rho0=1.0, rho_growth=10.0, rho_max=100.0)


@pytest.fixture
def problem():
    rng = np.random.default_rng(7)
    t = rng.uniform(0.0, 2.0 * np.pi, 40)
    X = np.column_stack([np.cos(t), np.sin(t), np.cos(t + 1), 0.3 * t])
    mask = rng.random(X.shape) > 0.2
    W = np.where(mask, X, 0.0)
    S0 = np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))
    return MaskedLeastSquares(W, mask), S0


def test_callback_sees_every_stage_as_the_result_records_it(problem, capsys):
    term, S0 = problem
    seen: list[StageInfo] = []
    with threadpool_limits(1):
        res = minimize_regularized(term, S0, callback=seen.append, verbose=True, **KW)
    assert res.status == CONVERGED and res.n_stages == 3
    assert [i.stage for i in seen] == [0, 1, 2] and all(i.n_stages == 3 for i in seen)
    np.testing.assert_array_equal([i.rho for i in seen], res.rho_history)
    np.testing.assert_array_equal([i.energy for i in seen], res.stage_energy)
    np.testing.assert_array_equal([i.rank for i in seen], res.rank_history)
    assert sum(i.nit for i in seen) == res.nit
    assert [i.nit for i in seen] == [int(np.sum(res.stage_of_iteration == k)) for k in range(3)]
    np.testing.assert_array_equal(seen[-1].x, res.x)
    assert all(i.converged and i.seconds >= 0.0 for i in seen)
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 3
    for info, line in zip(seen, lines, strict=True):
        assert f"rho {info.rho:g}" in line and f"{info.nit} iterations" in line


def test_callback_returning_true_stops_after_that_stage(problem):
    """Stopping after stage 1 gives exactly the solve whose schedule ends at that stage's rho."""
    term, S0 = problem
    with threadpool_limits(1):
        stopped = minimize_regularized(term, S0, callback=lambda info: info.stage == 1, **KW)
        short = minimize_regularized(term, S0, **{**KW, "rho_max": 10.0})
    assert stopped.status == INACCURATE and not stopped.success
    assert "stopped by the callback after stage 1" in stopped.message
    assert stopped.n_stages == 2
    np.testing.assert_array_equal(stopped.rho_history, [1.0, 10.0])
    np.testing.assert_array_equal(stopped.x, short.x)
    assert stopped.fun == short.fun and stopped.nit == short.nit


def test_callback_returning_true_at_the_last_stage_changes_nothing(problem):
    term, S0 = problem
    with threadpool_limits(1):
        res = minimize_regularized(term, S0, callback=lambda info: True if info.stage == 2 else None, **KW)
    assert res.status == CONVERGED and res.n_stages == 3


def test_verbose_off_prints_nothing(problem, capsys):
    term, S0 = problem
    with threadpool_limits(1):
        minimize_regularized(term, S0, **{**KW, "rho_max": 1.0})
    assert capsys.readouterr().out == ""


def test_a_callback_that_is_not_callable_is_refused(problem):
    term, S0 = problem
    with pytest.raises(ValueError, match="callback"):
        minimize_regularized(term, S0, callback=3, **KW)
