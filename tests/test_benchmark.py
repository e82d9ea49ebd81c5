"""The benchmark experiment's parts: the missingness mechanisms (their defining property, with margins
from the draw's own standard errors), the degenerate-draw rule, and the tidy table's schema and ranks
(brute force on small frames)."""

import numpy as np
import pandas as pd
import pytest

from nldr.experiments import get
from nldr.experiments._benchmark import METHODS, load_dataset, make_estimators, ranks, summarise
from nldr.experiments._missingness import (
    MIN_OBSERVED_PER_COLUMN,
    draw_mask,
    mar_drivers,
    mar_mask,
    mcar_mask,
    mnar_mask,
)


def _sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))


def _gaussian_grid():
    z = np.linspace(-8, 8, 16001)
    w = np.exp(-0.5 * z**2)
    return z, w / w.sum()


def test_mcar_hides_share_p_within_five_binomial_standard_errors():
    X = np.zeros((400, 10))
    for p in (0.1, 0.25, 0.5):
        hidden = ~mcar_mask(X, p, seed=3)
        se = np.sqrt(p * (1 - p) / X.size)
        assert abs(hidden.mean() - p) < 5 * se


def test_mnar_hides_larger_values_by_the_amount_its_formula_predicts():
    # z ~ N(0, 1) per column; P(hidden | z) = sigmoid(a + s z) with mean rate p. The expected gap
    # E[z | hidden] - E[z | observed] follows from the formula by quadrature; the draw's gap must lie
    # within 5 standard errors of it (se from the two groups' sample sizes, unit variance bounds).
    rng = np.random.default_rng(0)
    X = rng.standard_normal((2000, 4))
    p, slope = 0.25, 2.0
    hidden = ~mnar_mask(X, p, seed=11, slope=slope)
    Z = (X - X.mean(axis=0)) / X.std(axis=0)
    gap = Z[hidden].mean() - Z[~hidden].mean()
    z, w = _gaussian_grid()
    low, high = -50.0, 50.0  # the intercept with rate p under N(0, 1) (bisection, as the module's)
    for _ in range(100):
        a = 0.5 * (low + high)
        low, high = (a, high) if (w * _sigmoid(a + slope * z)).sum() < p else (low, a)
    prob = _sigmoid(a + slope * z)
    expected = (w * prob * z).sum() / (w * prob).sum() - (w * (1 - prob) * z).sum() / (w * (1 - prob)).sum()
    se = np.sqrt(1 / hidden.sum() + 1 / (~hidden).sum())
    assert expected > 1.0  # the mechanism is strong at slope 2
    assert abs(gap - expected) < 5 * se + 0.03  # 0.03: the module fits the intercept to the sample
    assert abs(hidden.mean() - p) < 5 * np.sqrt(p * (1 - p) / hidden.size)


def test_mar_depends_on_the_named_driver_and_not_on_the_hidden_value():
    # independent columns: under MAR a masked column's hidden share rises with its driver, and the
    # hidden entries' own values are a random sample of the column (gap ~ 0 within 5 se)
    rng = np.random.default_rng(1)
    X = rng.standard_normal((3000, 6))
    mask = mar_mask(X, 0.25, seed=5, slope=2.0)
    drivers, masked = mar_drivers(X.shape[1], seed=5)
    assert set(drivers) & set(masked) == set()
    assert mask[:, np.setdiff1d(np.arange(6), masked)].all()  # the drivers are always observed
    for c, j in zip(drivers, masked, strict=True):
        hidden = ~mask[:, j]
        high = X[:, c] > np.median(X[:, c])
        # the driver: hidden share above its median far exceeds the share below (binomial se)
        r_hi, r_lo = hidden[high].mean(), hidden[~high].mean()
        se = np.sqrt(r_hi * (1 - r_hi) / high.sum() + r_lo * (1 - r_lo) / (~high).sum())
        assert r_hi - r_lo > 10 * se
        # the hidden value itself: no gap
        gap = X[hidden, j].mean() - X[~hidden, j].mean()
        assert abs(gap) < 5 * np.sqrt(1 / hidden.sum() + 1 / (~hidden).sum())
    # the whole matrix loses about p of its entries (half the columns at twice the rate)
    assert abs((~mask).mean() - 0.25) < 0.02


@pytest.mark.parametrize("mechanism", ["MCAR", "MAR", "MNAR"])
def test_no_row_is_all_missing_and_every_column_keeps_two_entries(mechanism):
    rng = np.random.default_rng(2)
    for seed in range(40):
        X = rng.standard_normal((5, 3))
        mask = draw_mask(X, mechanism, 0.6, seed)
        assert mask.any(axis=1).all()
        assert (mask.sum(axis=0) >= MIN_OBSERVED_PER_COLUMN).all()


def test_masks_repeat_with_their_seed_and_refuse_bad_input():
    X = np.random.default_rng(3).standard_normal((30, 4))
    for mechanism in ("MCAR", "MAR", "MNAR"):
        assert np.array_equal(draw_mask(X, mechanism, 0.25, 7), draw_mask(X, mechanism, 0.25, 7))
    with pytest.raises(ValueError, match="p must lie"):
        mcar_mask(X, 1.0, 0)
    with pytest.raises(ValueError, match="mechanism must be one of"):
        draw_mask(X, "MNARX", 0.25, 0)
    with pytest.raises(ValueError, match="slope"):
        mnar_mask(X, 0.25, 0, slope=0.0)
    with pytest.raises(ValueError, match="seed"):
        mcar_mask(X, 0.25, 1.5)


def _runs():
    """Two cells, two masks, three methods with known RMSEs: A best everywhere but one mask of cell 2."""
    rows = []
    table = {
        ("d1 MCAR p=0.1", 0): (1, 2, 3),
        ("d1 MCAR p=0.1", 1): (1, 3, 2),
        ("d2 MNAR p=0.25", 0): (2, 1, 3),
    }
    table[("d2 MNAR p=0.25", 1)] = (1, 2, 3)
    for (cell, mask), values in table.items():
        dataset, mechanism = cell.split()[:2]
        for method, rmse in zip(("A", "B", "C"), values, strict=True):
            rows.append(
                {
                    "dataset": dataset,
                    "mechanism": mechanism,
                    "cell": cell,
                    "mask": mask,
                    "method": method,
                    "rmse": float(rmse),
                    "sse": 10.0 * rmse,
                }
            )
    frame = pd.DataFrame(rows)
    frame["rank"] = frame.groupby(["cell", "mask"])["rmse"].rank(method="average")
    return frame


def test_summary_ranks_and_wins_by_hand():
    table = summarise(_runs())
    assert list(table.columns) == ["setting", "method", "metric", "value"]
    v = table.set_index(["setting", "method", "metric"])["value"]
    # cell 1: A ranks 1, 1; cell 2: A ranks 2, 1 -> mean ranks 1 and 1.5, overall 1.25
    assert v[("d1 MCAR p=0.1", "A", "rank")] == 1.0 and v[("d2 MNAR p=0.25", "A", "rank")] == 1.5
    assert v[("all", "A", "mean_rank")] == 1.25
    # cell 2's mean RMSE: A 1.5, B 1.5 -> a shared win; B wins one mask there
    assert v[("all", "A", "wins")] == 2.0 and v[("all", "B", "wins")] == 1.0
    assert v[("d2 MNAR p=0.25", "B", "wins")] == 1.0 and v[("d1 MCAR p=0.1", "C", "wins")] == 0.0
    assert v[("dataset=d2", "C", "mean_rank")] == 3.0 and v[("mechanism=MCAR", "B", "mean_rank")] == 2.5
    assert v[("d1 MCAR p=0.1", "B", "rmse")] == 2.5 and v[("d1 MCAR p=0.1", "B", "n_masks")] == 2.0
    cells = ranks(_runs())
    assert list(cells.columns) == ["dataset", "mechanism", "cell", "method", "rmse", "rank", "win"]


def test_jobs_cells_and_caption_follow_the_config():
    benchmark = get("benchmark")
    config = {
        "benchmark": {
            "datasets": [
                {"name": "oil100", "source": "oil", "n_rows": 100},
                {"name": "wine", "source": "wine", "skip_mechanisms": ["MAR"]},
            ],
            "subsample_seed": 1,
            "missingness": [{"mechanism": "MCAR", "p": 0.1}, {"mechanism": "MAR", "p": 0.25}],
            "slope": 2.0,
            "n_masks": 10,
            "seed": 2016,
            "n_folds": 2,
            "methods": ["Ours", "mean"],
            "grids": {},
        }
    }
    ids = [job.id for job in benchmark.check(config)]
    assert ids == ["oil100_MCAR0.1", "oil100_MAR0.25", "wine_MCAR0.1"]
    assert not benchmark.in_paper
    assert "10 seeded masks" in benchmark.caption(config)
    config["benchmark"]["datasets"].append({"name": "wine", "source": "diabetes"})
    with pytest.raises(ValueError, match="share a name"):
        benchmark.check(config)


def test_sklearn_sets_load_without_download_subsample_and_drop_constant_columns():
    X = load_dataset({"source": "digits", "n_rows": 100}, None, 5)
    assert X.shape[0] == 100 and (X.std(axis=0) > 0).all() and X.shape[1] < 64
    assert np.array_equal(X, load_dataset({"source": "digits", "n_rows": 100}, None, 5))
    with pytest.raises(ValueError, match="source"):
        load_dataset({"source": "iris"}, None, 0)


def test_every_method_gets_an_estimator_and_a_grid():
    W = np.random.default_rng(0).standard_normal((30, 5))
    W[0, 0] = np.nan
    known = [m for m in METHODS if m != "GP-LVM"]
    built = make_estimators(known, W, {"KNNImputer": {"n_neighbors": [3]}})
    assert list(built) == known
    assert built["KNNImputer"][1] == {"n_neighbors": [3]} and built["Ours"][1] == {}
    assert built["missForest"][0].estimator.n_estimators == 100
    with pytest.raises(ValueError, match="unknown method"):
        make_estimators(["PCA"], W)
