"""Bookkeeping shared by the hold-out selections (:mod:`nldr.model_selection` for matrix problems,
:mod:`nldr.nrsfm._selection` for NRSfM): candidate grids, fold scores summarised per candidate, and
independent fold solves run in worker processes."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np
import pandas as pd

__all__ = ["positive_grid", "summarise_folds", "run_jobs", "say"]


def say(verbose, who: str, message: str) -> None:
    """Print one progress line ``[who] message`` (stdout, flushed) when ``verbose`` is true."""
    if verbose:
        print(f"[{who}] {message}", flush=True)


def positive_grid(values, name: str) -> np.ndarray:
    """``values`` as a sorted 1-d array of distinct finite numbers > 0; ValueError naming ``name``."""
    arr = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-d sequence of numbers; got shape {arr.shape}")
    if not np.all(np.isfinite(arr) & (arr > 0)):
        raise ValueError(f"{name} must all be finite and > 0; got {arr.tolist()}")
    return np.unique(arr)


def summarise_folds(rows: list[dict], keys: Sequence[str]) -> pd.DataFrame:
    """Per candidate (``keys``): mean and sample sd of ``test_error`` over folds, mean ``fit_time``."""
    frame = pd.DataFrame(rows)
    grouped = frame.groupby(list(keys), sort=True)
    out = grouped["test_error"].agg(mean_test_error="mean", std_test_error="std").reset_index()
    out["fit_time"] = grouped["fit_time"].mean().to_numpy()
    return out


def run_jobs(
    jobs: list[tuple[Callable, tuple]], n_jobs: int, done: Callable[[int, int, float], None] | None = None
) -> list:
    """``[fn(*args) for fn, args in jobs]``, in up to ``n_jobs`` processes (in order).

    ``done(finished, total, seconds)``, if given, is called in this process as each job finishes
    (``seconds`` since the first started): progress that shows in a notebook whatever ``n_jobs``.
    """
    start, results = time.perf_counter(), []
    if n_jobs == 1 or len(jobs) == 1:
        for fn, args in jobs:
            results.append(fn(*args))
            if done is not None:
                done(len(results), len(jobs), time.perf_counter() - start)
        return results
    with ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs))) as pool:
        futures = [pool.submit(fn, *args) for fn, args in jobs]
        for finished, _ in enumerate(as_completed(futures), start=1):
            if done is not None:
                done(finished, len(jobs), time.perf_counter() - start)
        return [f.result() for f in futures]
