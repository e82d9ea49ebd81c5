"""Tests of ``minimize_regularized(method="nystroem-warm")``: Nystroem stages, then exact final stage(s)."""

from __future__ import annotations

import numpy as np
import pytest

from nldr.data_terms import MaskedLeastSquares
from nldr.regularizer import minimize_regularized, reduced_energy

GAMMA, TAU = 0.3, 0.1
WARM = {"method": "nystroem-warm", "options": {"landmarks": 12}}


def warm(**options):
    """``minimize_regularized`` keyword arguments of the warm path with further options."""
    return {"method": "nystroem-warm", "options": {"landmarks": 12, **options}}


def nystroem(m, scale=None):
    return {"method": "nystroem", "options": {"landmarks": m, "scale": scale}}


#: The stages of a schedule started at rho0 = 1 run in its units (scale sqrt(rho0) = 1): a solve that
#: repeats its last stages alone from rho0 = 1e3 says so to take the same steps.
UNIT = {"scale": 1.0}
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
    res = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **warm(exact_stages=exact_stages))
    rhos = [1.0, 10.0, 100.0, 1e3]
    first_exact = len(rhos) - exact_stages  # solved on the Nystroem kernel, then again exactly
    first = minimize_regularized(
        term, S0, gamma=GAMMA, tau=TAU, rho0=1.0, rho_max=rhos[first_exact], **nystroem(12)
    )
    exact = minimize_regularized(
        term, first.x, gamma=GAMMA, tau=TAU, rho0=rhos[first_exact], rho_max=1e3, options=UNIT
    )
    np.testing.assert_array_equal(res.x, exact.x)
    assert res.fun == exact.fun
    np.testing.assert_array_equal(res.C, exact.C)
    assert res.n_stages == len(rhos) + 1
    np.testing.assert_array_equal(res.rho_history, rhos[: first_exact + 1] + rhos[first_exact:])
    np.testing.assert_array_equal(res.stage_energy, np.concatenate([first.stage_energy, exact.stage_energy]))
    assert res.nit == first.nit + exact.nit
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
    for options in ({"method": "exact"}, {"method": "nystroem-warm", "options": {"exact_stages": 4}},
                    {"method": "nystroem-warm", "options": {"landmarks": 40}}, nystroem(40)):  # fmt: skip
        other = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **options)
        np.testing.assert_array_equal(other.x, base.x)
        assert other.fun == base.fun and other.nit == base.nit


def test_warm_start_is_validated(problem):
    term, S0 = problem
    with pytest.raises(ValueError, match="method must be one of"):
        minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, method="landmarks")
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="exact_stages"):
            minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **warm(exact_stages=bad))
    with pytest.raises(ValueError, match="landmarks"):
        minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **warm(landmarks=0))


def test_all_exact_stages_with_few_landmarks_is_the_exact_solver(problem):
    """exact_stages >= the number of stages: the exact solver throughout, even with landmarks < n."""
    term, S0 = problem
    base = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE)
    other = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **warm(exact_stages=4))
    np.testing.assert_array_equal(other.x, base.x)
    assert other.fun == base.fun and other.nit == base.nit


def test_exact_tol_stops_the_exact_stage_on_an_energy_plateau(problem):
    """With exact_tol the exact stage is the same L-BFGS run cut at the first iteration where the
    energy fell by at most 10 * exact_tol * max(|E|, 1) over the last 10 iterations."""
    term, S0 = problem
    full = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **WARM)
    exact_tol = 3e-4
    cut = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **warm(exact_tol=exact_tol))
    last = cut.stage_of_iteration == cut.n_stages - 1
    full_last = full.energy_history[full.stage_of_iteration == full.n_stages - 1]
    energies = cut.energy_history[last]
    k = energies.size
    assert 10 <= k < full_last.size  # the rule cut the run short, after a full window
    # The same iterates up to the cut (the rule only stops L-BFGS, it does not change its steps).
    np.testing.assert_array_equal(energies, full_last[:k])
    np.testing.assert_array_equal(cut.energy_history[~last], full.energy_history[: (~last).sum()])
    # E_0: the exact energy at the Nystroem answer (the stage's start).
    start = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **nystroem(12))
    e0, _ = reduced_energy(start.x, term, gamma=GAMMA, tau=TAU, rho=1e3)
    history = np.concatenate([[e0], energies])
    decrease = history[:-10] - history[10:]  # over 10 iterations, ending at iterations 10 .. k
    bound = 10 * exact_tol * np.maximum(np.abs(history[10:]), 1.0)
    assert decrease[-1] <= bound[-1] and np.all(decrease[:-1] > bound[:-1])
    assert cut.fun == energies[-1]
    value, _ = reduced_energy(cut.x, term, gamma=GAMMA, tau=TAU, rho=1e3, eigensolver="full")
    assert cut.fun == pytest.approx(value, rel=1e-12)
    assert cut.status == 0 and cut.fun >= full.fun - 1e-12 * abs(full.fun)


def test_last_landmarks_changes_only_the_last_nystroem_stage(problem):
    """last_landmarks = m2: the warm start's stages are the m-landmark solve up to the last Nystroem
    stage, then that stage on m2 landmarks (same seed), then the exact stage."""
    term, S0 = problem
    res = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **warm(last_landmarks=20))
    early = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, rho0=1.0, rho_max=100.0, **nystroem(12))
    late = minimize_regularized(
        term, early.x, gamma=GAMMA, tau=TAU, rho0=1e3, rho_max=1e3, **nystroem(20, scale=1.0)
    )
    exact = minimize_regularized(term, late.x, gamma=GAMMA, tau=TAU, rho0=1e3, rho_max=1e3, options=UNIT)
    np.testing.assert_array_equal(res.x, exact.x)
    np.testing.assert_array_equal(res.stage_energy, np.concatenate([early.stage_energy, late.stage_energy,
                                                                    exact.stage_energy]))  # fmt: skip
    assert res.nit == early.nit + late.nit + exact.nit


def test_exact_tol_and_last_landmarks_are_validated(problem):
    term, S0 = problem
    bad_values = (("exact_tol", 0.0), ("exact_tol", -1e-6), ("last_landmarks", 0), ("last_landmarks", 2.5))
    for name, bad in bad_values:
        with pytest.raises(ValueError, match=name):
            minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, **warm(**{name: bad}))
    for method in ("exact", "nystroem"):  # options of the warm path alone: refused, naming the method
        for name, value in (("exact_tol", 1e-6), ("last_landmarks", 20), ("exact_stages", 2)):
            options = {name: value} | ({"landmarks": 12} if method == "nystroem" else {})
            with pytest.raises(ValueError, match=f"method '{method}' takes no option '{name}'"):
                minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, method=method, options=options)


def test_every_method_lists_its_options_when_one_is_unknown(problem):
    term, S0 = problem
    for method, options in (("exact", {}), ("nystroem", {"landmarks": 12}), ("nystroem-warm", {})):
        with pytest.raises(ValueError, match=f"method '{method}' takes no option 'landmark'.*max_inner"):
            options = {**options, "landmark": 5}
            minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, method=method, options=options)
    with pytest.raises(ValueError, match="method 'nystroem' takes no option 'eigensolver'"):
        options = {"landmarks": 12, "eigensolver": "full"}
        minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, method="nystroem", options=options)
    with pytest.raises(ValueError, match="options must be a mapping"):
        minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, options=[("tol", 1e-8)])


def test_last_stage_only_keeps_the_full_schedules_units_and_copies():
    from nldr._options import last_stage_only

    full = {"rho0": 4.0, "rho_growth": 10.0, "rho_max": 400.0, "options": {"tol": 1e-8}, "method": "exact"}
    last = last_stage_only(full)
    assert last == {
        "rho0": 400.0, "rho_growth": 10.0, "rho_max": 400.0, "method": "exact",
        "options": {"tol": 1e-8, "scale": 2.0},
    }  # fmt: skip
    assert full["options"] == {"tol": 1e-8} and full["rho0"] == 4.0  # the input is not changed
    # a scale the caller set wins; absent keys take the caller's defaults
    assert last_stage_only({"options": {"scale": 3.0}})["options"]["scale"] == 3.0
    defaults = last_stage_only({}, rho0=9.0, rho_max=10.0)
    assert defaults == {"rho0": 10.0, "rho_max": 10.0, "options": {"scale": 3.0}}

