"""Tests of ``minimize_regularized(warm_start="nystroem")``: Nystroem stages, then exact final stage(s)."""

from __future__ import annotations

import numpy as np
import pytest

from nldr.data_terms import MaskedLeastSquares
from nldr.regularizer import minimize_regularized, reduced_energy

GAMMA, TAU = 0.3, 0.1
WARM = {"warm_start": "nystroem", "landmarks": 12}
SCHEDULE = {"rho0": 1.0, "rho_growth": 10.0, "rho_max": 1e3}


@pytest.fixture
def problem():
    rng = np.random.default_rng(5)
    X = rng.standard_normal((40, 4))
    mask = rng.random(X.shape) > 0.3
    S0 = np.where(mask, X, 0.0)
    return MaskedLeastSquares(S0, mask), S0


@pytest.mark.parametrize("exact_stages", [1, 2])
def test_final_stages_are_the_exact_solvers_stages_from_the_nystroem_result(problem, exact_stages):
    """The composite path is, bit for bit, a Nystroem solve over the first stages followed by the exact
    solver over the last ones from its result: so its answer meets the exact solver's stopping test."""
    term, S0 = problem
    res = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **WARM, exact_stages=exact_stages)
    rhos = [1.0, 10.0, 100.0, 1e3]
    first_exact = len(rhos) - exact_stages  # solved on the Nystroem kernel, then again exactly
    warm = minimize_regularized(
        term, S0, gamma=GAMMA, tau=TAU, rho0=1.0, rho_max=rhos[first_exact], landmarks=12
    )
    exact = minimize_regularized(term, warm.x, gamma=GAMMA, tau=TAU, rho0=rhos[first_exact], rho_max=1e3)
    np.testing.assert_array_equal(res.x, exact.x)
    assert res.fun == exact.fun
    np.testing.assert_array_equal(res.C, exact.C)
    assert res.n_stages == len(rhos) + 1
    np.testing.assert_array_equal(res.rho_history, rhos[: first_exact + 1] + rhos[first_exact:])
    np.testing.assert_array_equal(res.stage_energy, np.concatenate([warm.stage_energy, exact.stage_energy]))
    assert res.nit == warm.nit + exact.nit
    # ``fun`` is the exact reduced energy (not the Nystroem one) at the returned x.
    value, _ = reduced_energy(res.x, term, gamma=GAMMA, tau=TAU, rho=1e3, eigensolver="full")
    assert res.fun == pytest.approx(value, rel=1e-12)


def test_final_stage_is_a_stationary_point_of_the_exact_energy(problem):
    """Restarting the exact last stage from the answer finds no descent worth one ftol step."""
    term, S0 = problem
    res = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **WARM)
    again = minimize_regularized(term, res.x, gamma=GAMMA, tau=TAU, rho0=1e3, rho_max=1e3)
    # L-BFGS stopped on a relative decrease <= tol = 1e-10 per iteration (or gtol); a restart from a
    # stationary point can only gain rounding-level and tol-level amounts.
    assert again.fun >= res.fun - 1e-8 * max(abs(res.fun), 1.0)


def test_option_off_and_all_exact_match_the_default_bit_for_bit(problem):
    term, S0 = problem
    base = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE)
    for options in ({"warm_start": None, "exact_stages": 3}, {"warm_start": "nystroem", "exact_stages": 4},
                    {"warm_start": "nystroem", "landmarks": 40}):  # fmt: skip
        other = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **options)
        np.testing.assert_array_equal(other.x, base.x)
        assert other.fun == base.fun and other.nit == base.nit


def test_warm_start_is_validated(problem):
    term, S0 = problem
    with pytest.raises(ValueError, match="warm_start"):
        minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, warm_start="landmarks")
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="exact_stages"):
            minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, warm_start="nystroem", exact_stages=bad)
    with pytest.raises(ValueError, match="landmarks"):
        minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, warm_start="nystroem", landmarks=0)
