"""The robust_nrsfm experiment: jobs, the Huber kernel's start and parameters, summary (synthetic data)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from conftest import synthetic_sequence

from nldr.experiments import _robust_nrsfm as module
from nldr.experiments import get
from nldr.experiments._robust_nrsfm import METHODS, huber_kernel_parameters, robust_tnh_tau, run_displaced
from nldr.kernels import rbf_kernel
from nldr.model_selection import robust_scale
from nldr.nrsfm import OrthographicReprojection

SETTINGS = {
    "displacement_sd": {"low": 3.0, "high": 6.0},
    "tnh": {"tol": 1e-6},
    "robust_tnh": {"tau_factor": 0.6, "tol": 1e-6},
    "tau": 1e-4,
    "width": "d_med",
    "regularizer": {"rho0": 1e-2, "rho_growth": 100.0, "rho_max": 10.0, "depth_scale": 100.0},
    "huber": {"delta_factor": 1.345, "balance": 1.0, "regularizer": {"max_inner": 200}},
}


def small_case():
    X, W, R = synthetic_sequence(n_frames=12, n_points=8, seed=5)
    return X, W, R


def test_jobs_and_checks():
    exp = get("robust_nrsfm")
    config = {
        "robust_nrsfm": {
            **SETTINGS,
            "sequences": ["yoga", "pickup"],
            "step": 10,
            "displaced": [0.05, 0.1],
            "n_seeds": 3,
            "seed": 7,
        }
    }
    jobs = exp.check(config)
    assert [j.id for j in jobs] == [f"{s}_seed{7 + k}" for s in ("yoga", "pickup") for k in range(3)]
    assert all(j.params["displaced"] == [0.05, 0.1] for j in jobs)
    bad = {"robust_nrsfm": {**config["robust_nrsfm"], "displacement_sd": {"low": 5.0, "high": 3.0}}}
    with pytest.raises(ValueError, match="robust_nrsfm.displacement_sd"):
        exp.check(bad)
    bad = {"robust_nrsfm": {**config["robust_nrsfm"], "width": "d_min"}}
    with pytest.raises(ValueError, match="robust_nrsfm.width"):
        exp.check(bad)


def test_huber_kernel_starts_from_the_robust_tnh(monkeypatch):
    """Kernel (LS) starts from TNH's shapes and Kernel (Huber) from TNH (robust)'s, with its delta and tau
    given by huber_kernel_parameters on that start."""
    X, W, R = small_case()
    calls = []
    real = module.reconstruct

    def spy(*a, **kw):
        calls.append((a, kw, real(*a, **kw)))
        return calls[-1][2]

    monkeypatch.setattr(module, "reconstruct", spy)
    rows, arrays = run_displaced(W, R, X, shares=[0.1], seed=3, settings=SETTINGS, name="synthetic")
    assert list(rows["method"]) == list(METHODS)
    (_, tnh_kw, tnh), (_, robust_kw, robust), (_, ls_kw, ls), (hub_args, hub_kw, hub) = calls
    assert (tnh_kw["prior"], tnh_kw.get("loss", "squared")) == ("tnh", "squared")
    assert (robust_kw["prior"], robust_kw["loss"]) == ("tnh", "huber")  # the robust TNH
    assert ls_kw["start"] is tnh and ls_kw["tau"] == SETTINGS["tau"] and ls.loss == "squared"
    assert hub_kw["start"] is robust and hub.loss == "huber"
    assert hub.delta == rows.loc[rows["method"] == "Kernel (Huber)", "delta"].item()
    assert hub.tau == rows.loc[rows["method"] == "Kernel (Huber)", "tau"].item()
    assert hub_kw["max_inner"] == 200  # the Huber block's own regularizer options apply
    tau_r = robust_tnh_tau((12, 24), 0.6)
    corrupted = OrthographicReprojection(hub_args[0], None, R)  # the displaced tracks the Huber solve saw
    delta, tau = huber_kernel_parameters(corrupted, robust.x, tau_r, hub.gamma, 1.345, 1.0)
    assert (delta, tau) == (hub.delta, hub.tau)
    # the saved arrays: one reconstruction per method, and which coordinates were displaced
    recon = arrays[0.1]
    assert set(recon.shapes) == set(METHODS)
    assert recon.extra["displaced"].sum() == round(0.1 * W.size)


def test_huber_kernel_parameters_follow_their_definition():
    X, W, R = small_case()
    term = OrthographicReprojection(W, None, R)
    rng = np.random.default_rng(0)
    start = X + 0.01 * rng.standard_normal(X.shape)
    gamma = 0.05
    delta, tau = huber_kernel_parameters(term, start, 2.0, gamma, 1.345, 0.5)
    r = term.residuals(start)
    assert delta == pytest.approx(1.345 * robust_scale(r), rel=1e-12)  # no residual is zero here
    spectrum = np.sqrt(np.clip(np.linalg.eigvalsh(rbf_kernel(start, gamma)), 0, None)).sum()
    nuclear = np.linalg.svd(start, compute_uv=False).sum()
    assert tau / (2 * delta) == pytest.approx(0.5 * 2.0 * nuclear / spectrum, rel=1e-12)


def test_summarise_means_over_seeds_and_sequences():
    rows = []
    for seq, base in (("yoga", 1.0), ("pickup", 2.0)):
        for seed in (1, 2):
            for c in (0.05, 0.1):
                for k, method in enumerate(METHODS):
                    rows.append(
                        {
                            "sequence": seq,
                            "displaced": c,
                            "seed": seed,
                            "method": method,
                            "e3d": base + k + seed / 10 + c,
                        }
                    )
    table = get("robust_nrsfm").summarise(pd.DataFrame(rows))
    assert list(table.columns) == ["setting", "method", "metric", "value"]
    assert set(table["setting"]) == {
        "Pickup displaced=0.05",
        "Pickup displaced=0.1",
        "Yoga displaced=0.05",
        "Yoga displaced=0.1",
        "Mean displaced=0.05",
        "Mean displaced=0.1",
    }
    assert set(table["method"]) == set(METHODS)

    def value(setting, method, metric="e3d"):
        sel = table[(table["setting"] == setting) & (table["method"] == method) & (table["metric"] == metric)]
        return sel["value"].item()

    assert value("Yoga displaced=0.1", "TNH") == pytest.approx(1.0 + 0.15 + 0.1)
    assert value("Yoga displaced=0.1", "TNH", "e3d_sd") == pytest.approx(np.std([1.1, 1.2], ddof=1))
    # the Mean is the mean over sequences of their means over seeds
    assert value("Mean displaced=0.1", "Kernel (Huber)") == pytest.approx(1.5 + 3 + 0.15 + 0.1)
    assert value("Mean displaced=0.1", "Kernel (Huber)", "n_sequences") == 2
    with pytest.raises(ValueError, match="runs lacks columns"):
        get("robust_nrsfm").summarise(pd.DataFrame(rows).drop(columns="displaced"))
