"""Tests of the robust data terms (nldr.data_terms.Huber, MaskedHuber) and of linear Robust PCA
(nldr._baselines.rpca), from the mathematics: finite differences, the least-squares limit, the kink,
optimality certificates and cvxpy's optimum."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from nldr._baselines.rpca import default_pcp_lambda, pcp_objective, rpca_impute, rpca_pcp
from nldr.data_terms import DataTerm, Huber, MaskedHuber, MaskedLeastSquares, huber_loss
from nldr.experiments._robust import gross_corruption
from nldr.model_selection import median_gamma, robust_scale
from nldr.nrsfm import OrthographicReprojection
from nldr.regularizer import minimize_regularized


@pytest.fixture(autouse=True)
def single_blas_thread():
    with threadpool_limits(1):
        yield


def _problem(seed=0, n=8, d=5):
    rng = np.random.default_rng(seed)
    W = rng.standard_normal((n, d))
    mask = rng.random((n, d)) > 0.3
    S = W + rng.standard_normal((n, d))  # residuals of both signs, some beyond delta
    return W, mask, S


def _nrsfm_term(seed=1, F=4, P=5):
    rng = np.random.default_rng(seed)
    R = rng.standard_normal((F, 2, 3))
    W2d = rng.standard_normal((F, 2 * P))
    mask = rng.random((F, P)) > 0.2
    mask[:, 0] = True
    return OrthographicReprojection(W2d, mask, R), rng.standard_normal((F, 3 * P))


def _fd_gradient(fun, S, h=1e-6):
    G = np.zeros_like(S)
    for idx in np.ndindex(S.shape):
        E = np.zeros_like(S)
        E[idx] = h
        G[idx] = (fun(S + E) - fun(S - E)) / (2 * h)
    return G


def _fd_jacobian(fun, S, h=1e-6):
    x = S.ravel()
    cols = []
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = h
        cols.append((fun((x + e).reshape(S.shape)) - fun((x - e).reshape(S.shape))) / (2 * h))
    return np.stack(cols, axis=1)


def test_huber_loss_values_and_kink():
    delta = 0.5
    r = np.array([-2.0, -0.5, -0.2, 0.0, 0.3, 0.5, 1.0])
    expected = np.array([2 * 0.5 * 2 - 0.25, 0.25, 0.04, 0.0, 0.09, 0.25, 2 * 0.5 * 1 - 0.25])
    np.testing.assert_allclose(huber_loss(r, delta), expected, rtol=0, atol=1e-15)
    # at the kink both branches agree in value (delta^2) and slope (2 delta): C1, not C2
    for side in (-1.0, 1.0):
        k = side * delta
        left, right = huber_loss(k - 1e-7, delta), huber_loss(k + 1e-7, delta)
        assert (right - left) / 2e-7 == pytest.approx(2 * k, rel=1e-6)
    assert np.all(huber_loss(r, delta) <= r * r)


def test_huber_l1_limit():
    # h_delta / (2 delta) -> |r|, within delta / 2 everywhere
    r = np.linspace(-3, 3, 61)
    for delta in (1e-1, 1e-3):
        assert np.max(np.abs(huber_loss(r, delta) / (2 * delta) - np.abs(r))) <= delta / 2 + 1e-15


@pytest.mark.parametrize("delta", [0.1, 0.7, 3.0])
def test_masked_huber_gradient_matches_finite_differences(delta):
    W, mask, S = _problem()
    term = MaskedHuber(W, mask, delta)
    assert isinstance(term, DataTerm)
    r = np.abs((W - S)[mask])
    S = S + np.where(np.abs(np.abs(W - S) - delta) < 1e-4, 1e-3, 0.0)  # stay off the kink for FD
    assert r.min() < delta < r.max() or delta == 3.0
    np.testing.assert_allclose(term.gradient(S), _fd_gradient(term.value, S), rtol=1e-6, atol=1e-7)
    # the generic J^T psi form agrees with the direct one
    np.testing.assert_allclose(Huber.gradient(term, S), term.gradient(S), rtol=0, atol=1e-14)


def test_masked_huber_residual_form():
    W, mask, S = _problem(3)
    term = MaskedHuber(W, mask, 0.6)
    rt = term.residuals(S)
    assert float(rt @ rt) == pytest.approx(term.value(S), rel=1e-14)
    J = term.jacobian(S).toarray()
    np.testing.assert_allclose(J, _fd_jacobian(term.residuals, S), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose((2 * J.T @ rt).reshape(S.shape), term.gradient(S), atol=1e-12)


def test_masked_huber_equals_least_squares_within_delta():
    W, mask, S = _problem(2)
    ls = MaskedLeastSquares(W, mask)
    big = float(np.abs(W - S)[mask].max())
    for delta in (big, 10 * big, 1e6):
        hub = MaskedHuber(W, mask, delta)
        # the same n squares summed in two orders (BLAS dot vs numpy's pairwise sum): each sum errs by
        # at most about n eps times the sum of its (non-negative) terms, i.e. n eps ls.value
        n = int(mask.sum())
        assert abs(hub.value(S) - ls.value(S)) <= n * np.finfo(float).eps * ls.value(S)
        # elementwise, no reduction: clip is the identity inside delta and sqrt(|r| |r|) = |r| in IEEE
        np.testing.assert_array_equal(hub.gradient(S), ls.gradient(S))
        np.testing.assert_array_equal(hub.residuals(S), ls.residuals(S))
    small = MaskedHuber(W, mask, 0.05)
    assert small.value(S) < ls.value(S)
    # gross residuals pull with force 2 delta at most
    assert np.max(np.abs(small.gradient(S))) <= 2 * 0.05


def test_masked_huber_rejects_bad_input():
    W, mask, _ = _problem()
    for delta in (0.0, -1.0, np.inf, np.nan, "a"):
        with pytest.raises(ValueError, match="delta"):
            MaskedHuber(W, mask, delta)
    with pytest.raises(ValueError, match="same shape"):
        MaskedHuber(W, mask[:, :-1], 1.0)
    with pytest.raises(ValueError, match="mask must be boolean"):
        MaskedHuber(W, np.full(W.shape, 2), 1.0)
    with pytest.raises(ValueError, match="term must implement"):
        Huber(np.zeros((3, 3)), 1.0)
    with pytest.raises(ValueError, match="S0 must have the data term's shape"):
        minimize_regularized(MaskedHuber(W, mask, 1.0), W[:-1], gamma=0.1, tau=0.1)


@pytest.mark.parametrize("delta", [0.2, 1.5])
def test_huber_reprojection_gradient_and_least_squares_limit(delta):
    term, X = _nrsfm_term()
    robust = Huber(term, delta)
    assert isinstance(robust, DataTerm) and robust.shape == term.shape
    r = np.abs(term.residuals(X))
    assert r.min() < delta < r.max()
    np.testing.assert_allclose(robust.gradient(X), _fd_gradient(robust.value, X), rtol=1e-6, atol=1e-7)
    J = robust.jacobian(X).toarray()
    np.testing.assert_allclose(J, _fd_jacobian(robust.residuals, X), rtol=1e-6, atol=1e-7)
    wide = Huber(term, 2 * float(r.max()))
    assert wide.value(X) == pytest.approx(term.value(X), rel=1e-15)
    np.testing.assert_allclose(wide.gradient(X), term.gradient(X), rtol=1e-13, atol=1e-13)
    with pytest.raises(ValueError, match="delta"):
        Huber(term, 0.0)


def test_minimize_regularized_with_huber_resists_gross_errors():
    # A closed curve in R^8 with 10 % of its entries given errors of 3-6 column sd. At the same tau and
    # gamma, least squares reproduces the errors (the regularizer cannot tell them from data); the
    # Huber term with delta from the MAD rule bounds their pull (2 delta) and the fit stays near the
    # clean curve. A behavioural check: it fails if the Huber term's gradient or scale were wrong.
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 2 * np.pi, 40))
    X = np.column_stack(
        [np.cos(t), np.sin(t), np.cos(t + 1), np.sin(t + 1), np.cos(2 * t), np.sin(2 * t), 0.3 * t, 0.3 * t]
    )
    mask = np.ones(X.shape, dtype=bool)
    W, _ = gross_corruption(X, mask, [0.1], 3)[0.1]
    gamma, tau = 0.25 * median_gamma(W, mask), 1.0
    ls = minimize_regularized(MaskedLeastSquares(W, mask), W, gamma=gamma, tau=tau)
    delta = 1.345 * robust_scale((W - ls.x)[mask])
    hub = minimize_regularized(MaskedHuber(W, mask, delta), W, gamma=gamma, tau=tau)
    assert ls.success and hub.success
    assert np.sum((hub.x - X) ** 2) < 0.1 * np.sum((ls.x - X) ** 2)


def test_robust_scale_and_corruption():
    g = np.random.default_rng(1).standard_normal(20001)
    assert robust_scale(g) == pytest.approx(1.0, abs=0.03)  # consistent at the Gaussian (se ~ 0.011)
    # 30 % gross errors of +-1e6: the median |r| is then the 0.5 / 0.7 quantile of |N(0, 1)|, 1.067,
    # so the scale is 1.4826 x 1.067 = 1.58, not ~5e5 like the standard deviation
    r = g.copy()
    r[:6000] = np.where(np.arange(6000) % 2, 1e6, -1e6)
    assert robust_scale(r) == pytest.approx(1.4826 * 1.0676, abs=0.05)
    with pytest.raises(ValueError, match="zero median absolute deviation"):
        robust_scale(np.zeros(5))
    X = np.arange(60.0).reshape(20, 3)
    mask = np.ones(X.shape, dtype=bool)
    mask[0] = False
    out = gross_corruption(X, mask, [0.05, 0.2], 7)
    small, big = out[0.05][1], out[0.2][1]
    assert small.sum() == round(0.05 * mask.sum()) and big.sum() == round(0.2 * mask.sum())
    assert np.all(big[small]) and not np.any(big & ~mask)  # nested, observed entries only
    error = np.abs(out[0.2][0] - X)[big] / np.broadcast_to(X.std(axis=0), X.shape)[big]
    assert np.all((error >= 3.0 - 1e-12) & (error <= 6.0 + 1e-12))
    np.testing.assert_array_equal(out[0.2][0][~big], X[~big])


# ---- Robust PCA --------------------------------------------------------------------------------


def _rpca_case(seed=0, n=30, d=10):
    rng = np.random.default_rng(seed)
    L0 = rng.standard_normal((n, 2)) @ rng.standard_normal((2, d))
    S0 = np.where(rng.random((n, d)) < 0.1, 5 * rng.standard_normal((n, d)), 0.0)
    W = L0 + S0 + 0.01 * rng.standard_normal((n, d))
    mask = rng.random((n, d)) > 0.2
    return W, mask


def test_rpca_optimality_conditions():
    W, mask = _rpca_case()
    res = rpca_pcp(W, mask, tol=1e-9, center=False)
    assert res.success
    lam, Y, S = res.lam, res.Y, res.S
    # Y is exactly in lam d||P_O S||_1 ...
    assert np.all(np.abs(Y[mask]) <= lam * (1 + 1e-12))
    on = mask & (S != 0)
    np.testing.assert_allclose(Y[on], lam * np.sign(S[on]), rtol=1e-12)
    assert np.all(Y[~mask] == 0)
    # ... and within the dual residual of d||L||_*: U^T Y V = I, ||Y||_2 <= 1
    U, s, Vt = np.linalg.svd(res.L)
    r = res.rank
    slack = res.dual_residual
    np.testing.assert_allclose(U[:, :r].T @ Y @ Vt[:r].T, np.eye(r), atol=slack * 10)
    assert np.linalg.norm(Y, 2) <= 1 + 10 * slack
    assert res.gap <= 1e-6 * res.fun


def test_rpca_matches_cvxpy():
    cp = pytest.importorskip("cvxpy")
    W, mask = _rpca_case(1)
    res = rpca_pcp(W, mask, tol=1e-9, center=False)
    lam = default_pcp_lambda(mask)
    assert res.lam == lam
    L = cp.Variable(W.shape)
    objective = cp.normNuc(L) + lam * cp.sum(cp.abs(cp.multiply(mask.astype(float), W - L)))
    problem = cp.Problem(cp.Minimize(objective))
    problem.solve(solver="CLARABEL")
    # the optimum lies in ADMM's certified bracket [fun - gap, fun], up to Clarabel's own accuracy (1e-8)
    assert res.fun - res.gap - 1e-6 * res.fun <= problem.value <= res.fun + 1e-6 * res.fun
    assert pcp_objective(L.value, W, mask, lam) >= res.fun - res.gap - 1e-6 * res.fun
    np.testing.assert_allclose(res.L, L.value, atol=1e-4 * np.abs(res.L).max())


def test_rpca_recovers_sparse_corruption_and_completes():
    rng = np.random.default_rng(5)
    n, d = 60, 20
    L0 = rng.standard_normal((n, 2)) @ rng.standard_normal((2, d))
    corrupt = rng.random((n, d)) < 0.05
    W = L0 + np.where(corrupt, 10.0 * np.sign(rng.standard_normal((n, d))), 0.0)
    mask = rng.random((n, d)) > 0.1
    res = rpca_impute(W, mask, center=False)
    assert res.success
    assert np.linalg.norm(res.x - L0) < 1e-3 * np.linalg.norm(L0)  # exact recovery (Candes et al.)


def test_rpca_rejects_bad_input():
    W, mask = _rpca_case()
    with pytest.raises(ValueError, match="lam"):
        rpca_pcp(W, mask, lam=0.0)
    with pytest.raises(ValueError, match="lam_factor"):
        rpca_impute(W, mask, lam_factor=-1.0)
    with pytest.raises(ValueError, match="mu"):
        rpca_pcp(W, mask, mu=-1.0)
    with pytest.raises(ValueError, match="mask must have the shape"):
        rpca_pcp(W, mask[1:])
    empty = mask.copy()
    empty[:, 2] = False
    with pytest.raises(ValueError, match="no observed entry"):
        rpca_pcp(W, empty)


# ---- selection with gross errors ----------------------------------------------------------------


def test_absolute_fold_score_and_unknown_score():
    from nldr.model_selection import HoldoutSearch
    from nldr.model_selection._folds import fold_score

    W = np.zeros((2, 2))
    X_hat = np.array([[1.0, -3.0], [0.5, 0.0]])
    hidden = np.array([[True, True], [False, True]])
    assert fold_score(X_hat, W, hidden, "absolute") == pytest.approx(4.0 / 3.0)
    assert fold_score(X_hat, W, hidden) == pytest.approx(10.0 / 3.0)
    from sklearn.impute import SimpleImputer

    with pytest.raises(ValueError, match="'scoring' parameter of HoldoutSearch"):
        HoldoutSearch(SimpleImputer(), {}, scoring="huber").fit(np.ones((3, 2)))


def test_robust_scale_delta_is_the_rule_on_the_least_squares_fits_residuals_of_its_own_training_entries():
    from sklearn.base import BaseEstimator, TransformerMixin

    from nldr.model_selection import HoldoutSearch, RobustScaleDelta

    class ColumnMeans(TransformerMixin, BaseEstimator):
        """Every entry replaced by its column's observed mean (x ``scale`` unless loss is squared)."""

        def __init__(self, loss="huber", delta=1.0, scale=2.0):
            self.loss, self.delta, self.scale = loss, delta, scale

        def fit(self, X, y=None):
            factor = 1.0 if self.loss == "squared" else self.scale
            self.means_ = factor * np.nanmean(X, axis=0)
            return self

        def transform(self, X):
            return np.broadcast_to(self.means_, X.shape).copy()

    rng = np.random.default_rng(3)
    X = rng.standard_normal((40, 4))
    W = np.where(rng.random(X.shape) > 0.2, X, np.nan)
    observed = ~np.isnan(W)
    hook = RobustScaleDelta(2.0)
    expected = 2.0 * robust_scale((W - np.nanmean(W, axis=0))[observed])
    assert hook(ColumnMeans(), W) == {"delta": pytest.approx(expected, rel=1e-12)}
    search = HoldoutSearch(ColumnMeans(), {"scale": [1.0, 3.0]}, n_folds=2, derive=hook).fit(W)
    assert search.best_estimator_.delta == pytest.approx(expected, rel=1e-12)  # the refit: every entry
    with pytest.raises(ValueError, match="factor"):
        RobustScaleDelta(0.0)


def test_a_typo_in_a_huber_search_s_solver_options_is_refused_before_any_solve(monkeypatch):
    import nldr.impute._regularizer as module
    from nldr.impute import KernelRegularizerImputer
    from nldr.model_selection import HoldoutSearch, RobustScaleDelta

    calls = []
    monkeypatch.setattr(module, "minimize_regularized", lambda *a, **k: calls.append(1))
    W = np.where(np.random.default_rng(0).random((12, 3)) > 0.2, 1.0, np.nan)
    W[0] = 1.0
    for solver, match in [({"rho_max": -1.0}, "rho_max"), ({"tol": -1.0}, "tol"),
                          ({"method": "nystroem", "options": {"landmark": 5}}, "landmark"),
                          ({"delta": 0.0}, "delta"), ({"loss": "l1"}, "loss")]:  # fmt: skip
        # the refit's solver (the estimator's) and the folds' (fold_params) are both checked
        for estimator, folds in [
            (KernelRegularizerImputer(**{"loss": "huber", **solver}), {}),
            (KernelRegularizerImputer(loss="huber"), solver),
        ]:
            grid = {"tau": [0.1, 1.0]}
            search = HoldoutSearch(estimator, grid, path="tau", derive=RobustScaleDelta(), fold_params=folds)
            with pytest.raises(ValueError, match=match):
                search.fit(W)
    assert calls == []


def test_the_huber_loss_is_the_masked_huber_solve_and_least_squares_within_delta():
    """loss="huber" solves minimize_regularized with MaskedHuber (same bits as the direct call), and
    with delta above every residual it is the least-squares solve (the two data terms agree)."""
    from nldr._baselines._masked import mean_fill
    from nldr.data_terms import MaskedHuber
    from nldr.impute import KernelRegularizerImputer
    from nldr.regularizer import minimize_regularized

    rng = np.random.default_rng(4)
    t = rng.uniform(0, 2 * np.pi, 30)
    X = np.c_[np.cos(t), np.sin(t), 0.3 * np.cos(2 * t)]
    mask = rng.random(X.shape) > 0.2
    mask[:, 0] |= ~mask.any(axis=1)
    X[rng.random(X.shape) < 0.05] += 3.0  # a few gross errors
    W = np.where(mask, X, np.nan)
    kw = {"standardize": False, "gamma": 1.0, "tau": 0.1, "method": "exact", "rho_max": 100.0}
    kw["denoise"] = True  # the solve's S on every entry, to compare with the direct call
    huber = KernelRegularizerImputer(loss="huber", delta=0.05, **kw).fit(W)
    Z = np.where(mask, X, 0.0)
    direct = minimize_regularized(
        MaskedHuber(Z, mask, 0.05), mean_fill(Z, mask), gamma=1.0, tau=0.1, method="exact", rho_max=100.0
    )
    np.testing.assert_array_equal(huber.completed_, direct.x)
    wide = KernelRegularizerImputer(loss="huber", delta=1e6, **kw).fit_transform(W)
    ls = KernelRegularizerImputer(**kw).fit_transform(W)
    np.testing.assert_allclose(wide, ls, rtol=0, atol=1e-6 * np.abs(ls).max())


def test_robust_experiment_jobs_and_summary():
    import pandas as pd

    from nldr.experiments import get

    experiment = get("robust")
    config = {
        "robust": {
            "p": [0.0, 0.25],
            "n_seeds": 3,
            "seed": 10,
            "corrupt": [0.05, 0.1],
            "outlier_sd": {"low": 3.0, "high": 6.0},
            "grid": {"log10_tau": {"min": -1, "max": 1}},
        }
    }
    jobs = experiment.check(config)
    assert [j.id for j in jobs][:2] == ["p0_seed10", "p0_seed11"] and len(jobs) == 6
    runs = pd.DataFrame(
        [{"p": 0.25, "corrupt": 0.1, "seed": s, "method": "RPCA", "sse": v} for s, v in [(1, 2.0), (2, 4.0)]]
    )
    table = experiment.summarise(runs)
    row = table[(table["setting"] == "corrupt=0.1,p=0.25") & (table["metric"] == "sse")]
    assert float(row["value"].iloc[0]) == 3.0
    bad = {"robust": {**config["robust"], "outlier_sd": {"low": 6.0, "high": 3.0}}}
    with pytest.raises(ValueError, match="robust.outlier_sd"):
        experiment.check(bad)
