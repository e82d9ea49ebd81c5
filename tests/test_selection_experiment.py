"""The selection experiments (nldr.experiments._selection): the CV row never sees the hidden ground
truth, the oracle row is labelled and is the best grid point, same seed same answer; selection_full's
jobs and caption."""

from __future__ import annotations

import numpy as np
import pytest
from protocol import full_config, quick_config
from threadpoolctl import threadpool_limits

from nldr.experiments import _selection as module
from nldr.experiments import get
from nldr.experiments._table2 import random_mask
from nldr.experiments.base import Job

N, D, P, SEED = 30, 12, 0.25, 5
SETTINGS = {
    "n_rows": N,
    "n_folds": 2,
    "holdout": 0.1,
    "rule": "one_se",
    "fold_landmarks": None,
    "center": False,
    "schedule": {"rho0": 1.0, "rho_growth": 100.0, "rho_max": 1e4},
    "paper": {"gamma": 0.075, "tau": 0.1},
    "grid": {"log10_tau": {"min": -2.0, "max": -1.0, "num": 2}, "gamma_multiples": [0.25, 1.0]},
    "baselines": ["KNNImputer"],
}
JOB = Job(f"p{P:g}_seed{SEED}", {"p": P, "seed": SEED, "mask": 0})


def oil_like(seed=0):
    """(N, 12) rows near a 2-d curved manifold, oil-flow-like scale."""
    rng = np.random.default_rng(seed)
    t = rng.random((N, 2))
    return np.sin(t @ rng.normal(size=(2, D)) * 2.0) + 0.05 * rng.normal(size=(N, D))


def run_on(monkeypatch, X, settings=SETTINGS):
    monkeypatch.setattr(module, "load_oil", lambda split, data_dir: (X, np.zeros(len(X), dtype=int)))
    with threadpool_limits(1):
        return get("selection").run(JOB, settings, data_dir=None)


def test_cv_is_blind_to_the_hidden_truth_and_the_oracle_is_the_labelled_best_grid_point(monkeypatch):
    X = oil_like()
    hidden = ~random_mask(X.shape, P, SEED)
    X2 = X + np.where(hidden, np.random.default_rng(1).normal(size=X.shape), 0.0)  # differs where hidden
    a, b = run_on(monkeypatch, X), run_on(monkeypatch, X2)
    assert list(a.rows["method"]) == [module.PAPER, module.CV, module.ORACLE, "KNNImputer (CV)"]
    assert module.ORACLE == "Ours (oracle grid point)"
    for out in (a, b):
        rows = out.rows.set_index("method")
        # the oracle row is the smallest SSE of the grid, and the CV's refit is one grid point's solve
        assert rows.loc[module.ORACLE, "sse"] == out.arrays["oracle_sse"].min()
        at = (out.arrays["oracle_tau"] == rows.loc[module.CV, "tau"]) & (
            out.arrays["oracle_gamma"] == rows.loc[module.CV, "gamma"]
        )
        assert at.sum() == 1 and out.arrays["oracle_sse"][at][0] == rows.loc[module.CV, "sse"]
    # what CV sees is identical; what the oracle sees is not (else this test could not fail)
    ra, rb = a.rows.set_index("method"), b.rows.set_index("method")
    assert (ra.loc[module.CV, "tau"], ra.loc[module.CV, "gamma"]) == (
        rb.loc[module.CV, "tau"],
        rb.loc[module.CV, "gamma"],
    )
    for key in ("cv_tau", "cv_gamma", "cv_error", "cv_error_sd"):
        np.testing.assert_array_equal(a.arrays[key], b.arrays[key])
    assert not np.array_equal(a.arrays["oracle_sse"], b.arrays["oracle_sse"])


def test_same_seed_same_rows(monkeypatch):
    X = oil_like(2)
    a, b = run_on(monkeypatch, X), run_on(monkeypatch, X)
    timing = ["seconds", "cpu_seconds", "solves"]
    assert a.rows.drop(columns=timing).equals(b.rows.drop(columns=timing))
    for key in a.arrays:
        np.testing.assert_array_equal(a.arrays[key], b.arrays[key])


@pytest.mark.parametrize("config", [full_config(), quick_config()], ids=["full", "quick"])
def test_selection_full_inherits_selection_and_says_which_solves_are_approximate(config):
    full, own = get("selection_full"), config["selection_full"]
    s = full.settings(config)
    assert {k: s[k] for k in own} == own
    assert all(s[k] == v for k, v in config["selection"].items() if k not in own)
    assert len(full.jobs(config)) == len(s["p"]) * s["n_masks"]
    assert [j.params["seed"] for j in full.jobs(config)][: s["n_masks"]] == [
        s["seed"] + k for k in range(s["n_masks"])
    ]
    caption = full.caption(config)
    assert f"{s['n_rows']} training rows" in caption and "oracle" in caption
    if s.get("fold_landmarks"):
        assert f"Nystroem kernel on {s['fold_landmarks']} landmark rows" in caption
        assert "exact solves" in caption
    assert full.published(config) == []  # the paper's numbers are for 100 rows only


def test_exact_path_takes_more_exact_stages_at_low_p():
    full = {"exact_path": {"method": "nystroem-warm", "n_landmarks": 100, "options": {"exact_stages": 1},
                           "low_p": {"max_p": 0.1, "exact_stages": 2}}}  # fmt: skip
    warm = {"method": "nystroem-warm", "n_landmarks": 100, "options": {"exact_stages": 2}}
    assert module.exact_path(full, 0.05) == warm
    assert module.exact_path(full, 0.1)["options"]["exact_stages"] == 2
    assert module.exact_path(full, 0.25) == {**warm, "options": {"exact_stages": 1}}
    assert full["exact_path"]["options"]["exact_stages"] == 1  # the settings are not changed
    assert module.exact_path({}, 0.25) == module.exact_path({"exact_path": None}, 0.05) == {}
    cfg = full_config()
    assert get("selection").settings(cfg).get("exact_path") is None  # 100 rows: the default path
    assert get("selection_full").settings(cfg)["exact_path"]["method"] == "nystroem-warm"
    assert "Nystroem kernel and end with the exact solver" in get("selection_full").caption(cfg)
