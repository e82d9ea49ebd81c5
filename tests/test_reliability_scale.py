"""Reliability III: units of the data, contracts checked before the expensive part, a solve that does
nothing says so (the cases of docs/REPRODUCTION.md#scale and the adversarial pass on 1d7379e)."""

import subprocess
import warnings

import numpy as np
import pytest
import yaml
from protocol import REPO, SNAKEMAKE, quick_config

import nldr.datasets as datasets
from nldr._baselines import mean_impute
from nldr._schedule import penalty_schedule
from nldr.data_terms import MaskedLeastSquares
from nldr.datasets import DataError, load_oil, load_oil_rows
from nldr.experiments._table2 import random_mask
from nldr.experiments.base import float_counts
from nldr.kernels import d_med_width
from nldr.regularizer import LONG_SOLVE_ROWS, minimize_regularized
from nldr.result import INACCURATE

# --------------------------------------------------------------------------------------------------
# Scale: the equivalent problem takes the same iterates; a solve that does nothing is not "converged"


@pytest.fixture(scope="module")
def oil40():
    """The first 40 oil-flow rows, 30 % of the entries hidden (Table 2's mask generator, seed 2016)."""
    X = load_oil("train")[0][:40]
    return X, random_mask(X.shape, 0.3, 2016)


def _solve_at_scale(X, mask, s):
    """The 40-row solve on data scaled by s, with the exactly equivalent parameters: gamma from the
    scaled data (d_med_width, 1 / s^2 of the unit one), tau, rho0 and rho_max times s^2."""
    W = np.where(mask, X * s, np.nan)
    S0 = mean_impute(W, mask)
    res = minimize_regularized(
        MaskedLeastSquares(W, mask), S0, gamma=d_med_width(S0), tau=0.1 * s**2, rho0=s**2, rho_max=1e4 * s**2
    )
    return res, float(np.sum((res.x - X * s) ** 2)) / s**2


def test_equivalent_problems_take_the_same_iterates_at_every_scale(oil40):
    X, mask = oil40
    unit, sse = _solve_at_scale(X, mask, 1.0)
    assert unit.success and unit.nit > 100
    # Powers of two: every product and quotient of the scaled run is the unit run's times a power of
    # two, which rounding does not change, so the iterates must agree exactly.
    for s in (2.0**-20, 2.0**20):
        res, sse_s = _solve_at_scale(X, mask, s)
        np.testing.assert_array_equal(res.x / s, unit.x)
        np.testing.assert_array_equal(res.stage_of_iteration, unit.stage_of_iteration)
        assert sse_s == sse and res.fun / s**2 == unit.fun
    # 1e-6 and 1e6 are not powers of two: gamma and rho0 carry rounding of 1e-16 relative, which
    # L-BFGS amplifies over ~470 iterations as a different BLAS kernel would. The energy is the
    # quantity the solver controls (stopping test 1e-10 relative per iteration); the SSE sits on a
    # flat minimum (docs/PERFORMANCE.md: it drifts while the energy is flat), so it gets a looser bound.
    for s in (1e-6, 1e6):
        res, sse_s = _solve_at_scale(X, mask, s)
        assert res.success and "converged" in res.message
        assert res.fun / s**2 == pytest.approx(unit.fun, rel=1e-8)
        assert sse_s == pytest.approx(sse, rel=1e-5)
        assert abs(res.nit - unit.nit) <= 0.02 * unit.nit


def test_data_in_raw_units_with_unit_parameters_is_not_called_converged(oil40):
    """tau 0.1 and rho0 1 on data x 1e5: the kernel terms' gradient is below gtol at the start, no
    stage moves S0, and the result says so instead of "all 5 penalty stages converged"."""
    X, mask = oil40
    W = np.where(mask, X * 1e5, np.nan)
    S0 = mean_impute(W, mask)
    res = minimize_regularized(MaskedLeastSquares(W, mask), S0, gamma=d_med_width(S0), tau=0.1)
    np.testing.assert_array_equal(res.x, S0)
    assert not res.success and res.status == INACCURATE
    assert "converged" not in res.message and "unchanged" in res.message and "s^2" in res.message


# --------------------------------------------------------------------------------------------------
# Callback, schedule, long solves


@pytest.fixture(scope="module")
def small():
    rng = np.random.default_rng(0)
    X = rng.random((30, 4))
    mask = rng.random(X.shape) > 0.2
    mask[0] = True
    return MaskedLeastSquares(np.where(mask, X, np.nan), mask), np.where(mask, X, 0.5)


@pytest.mark.parametrize("stop", [np.True_, 1, "yes"], ids=["np.True_", "1", "str"])
def test_a_callback_stops_on_any_true_value(small, stop):
    term, S0 = small
    kw = dict(gamma=1.0, tau=0.1, rho_max=100.0)
    res = minimize_regularized(term, S0, callback=lambda info: stop if info.stage == 0 else None, **kw)
    first = minimize_regularized(term, S0, **{**kw, "rho_max": 1.0})
    assert res.status == INACCURATE and res.n_stages == 1
    np.testing.assert_array_equal(res.x, first.x)
    assert "stopped by the callback after stage 0" in res.message and "converged" not in res.message
    with pytest.raises(ValueError, match="callback must return a truth value"):
        minimize_regularized(term, S0, callback=lambda info: np.ones(2), **kw)


def test_the_number_of_penalty_stages_is_bounded_before_the_list_is_built():
    with pytest.raises(ValueError, match="rho_growth=1.0001 takes about 9.21e\\+04 stages"):
        penalty_schedule(1.0, 1.0001, 1e4)
    with pytest.raises(ValueError, match="at most 1000"):
        penalty_schedule(1.0, 1.0000001, 1e4)  # 92 million on 1d7379e
    assert len(penalty_schedule(1.0, 1.01, 1e4)) == 926


class _Sentinel(Exception):
    pass


class _StopAtFirstEvaluation(MaskedLeastSquares):
    """A data term whose first evaluation ends the solve: what came before it was the cheap part."""

    def value(self, S):
        raise _Sentinel


def test_a_long_exact_solve_warns_with_its_cost_before_the_first_evaluation():
    rng = np.random.default_rng(1)
    n = LONG_SOLVE_ROWS
    X = rng.random((n, 2))
    term = _StopAtFirstEvaluation(X, np.ones(X.shape, bool))
    with pytest.warns(UserWarning, match=rf"{n} samples on the exact kernel: expect about \d+ CPU minutes"):
        with pytest.raises(_Sentinel):
            minimize_regularized(term, X, gamma=1.0, tau=0.1)


def test_a_long_solve_on_landmarks_or_a_small_one_does_not_warn():
    rng = np.random.default_rng(1)
    landmarks = {"method": "nystroem", "options": {"landmarks": 50}}
    for n, extra in ((LONG_SOLVE_ROWS, landmarks), (LONG_SOLVE_ROWS - 1, {})):
        X = rng.random((n, 2))
        term = _StopAtFirstEvaluation(X, np.ones(X.shape, bool))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(_Sentinel):
                minimize_regularized(term, X, gamma=1.0, tau=0.1, **extra)


# --------------------------------------------------------------------------------------------------
# Smaller gaps: every bad input a ValueError naming it


@pytest.mark.parametrize("seed", [-1, None, "a", 1.5, True])
def test_landmark_seed_is_validated(small, seed):
    term, S0 = small
    with pytest.raises(ValueError, match="landmark_seed"):
        minimize_regularized(
            term, S0, gamma=1.0, tau=0.1, method="nystroem", options={"landmarks": 5, "landmark_seed": seed}
        )


@pytest.mark.parametrize("center", ["no", 0, None])
def test_center_takes_booleans_only(small, center):
    term, S0 = small
    with pytest.raises(ValueError, match="center must be True or False"):
        minimize_regularized(term, S0, gamma=1.0, tau=0.1, center=center)


def test_complex_data_and_an_all_false_mask_are_refused():
    W = np.ones((5, 3)) + 1j
    with pytest.raises(ValueError, match="W is complex"):
        MaskedLeastSquares(W, np.ones(W.shape, bool))
    with pytest.raises(ValueError, match="mask is all False"):
        MaskedLeastSquares(np.ones((5, 3)), np.zeros((5, 3), bool))


# --------------------------------------------------------------------------------------------------
# Data directory and loader contracts


@pytest.mark.realdata
def test_a_data_dir_that_is_a_file_falls_back_to_the_mirror_or_says_what_to_fix(tmp_path, monkeypatch):
    afile = tmp_path / "not-a-folder"
    afile.write_text("")
    monkeypatch.setenv("NLDR_DATA_DIR", str(afile))
    with pytest.warns(UserWarning, match="NLDR_DATA_DIR .* a file, not a folder.*mirror copy"):
        X, _ = load_oil("train")
    assert X.shape == (1000, 12)
    monkeypatch.setenv("NLDR_DATA_MIRROR", str(tmp_path / "empty-mirror"))
    with pytest.raises(DataError, match="cannot write into NLDR_DATA_DIR .*writable folder.*mirror has no"):
        load_oil("train")
    monkeypatch.delenv("NLDR_DATA_MIRROR")
    with pytest.raises(DataError, match="cannot write into NLDR_DATA_DIR .*NLDR_DATA_MIRROR"):
        load_oil("train")


@pytest.mark.realdata
def test_an_unwritable_data_dir_falls_back_to_the_mirror(tmp_path, monkeypatch):
    """Permissions cannot be taken from root, so the refusal is simulated where the OS would raise it."""

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(datasets.tempfile, "mkstemp", refuse)
    with pytest.warns(UserWarning, match="PermissionError: Permission denied.*mirror copy"):
        path = datasets.fetch("oil/DataTrn.txt", tmp_path / "data")
    assert path.is_file() and not (tmp_path / "data" / "oil" / "DataTrn.txt").exists()


@pytest.mark.parametrize("n", [0, 2.5, "10", True, 3001])
def test_load_oil_rows_checks_n_before_any_file(tmp_path, monkeypatch, n):
    monkeypatch.delenv("NLDR_DATA_MIRROR", raising=False)

    def no_download(*args, **kwargs):
        raise AssertionError("a download was attempted before n was checked")

    monkeypatch.setattr(datasets, "_download", no_download)
    monkeypatch.setattr(datasets, "load_oil", no_download)
    with pytest.raises(ValueError, match=r"n must be an integer in 1\.\.3000"):
        load_oil_rows(n, tmp_path)


# --------------------------------------------------------------------------------------------------
# Config integers


def test_float_counts_names_every_integer_key_written_as_a_float():
    schema = yaml.safe_load((REPO / "workflow/schemas/config.schema.yaml").read_text())
    config = quick_config()
    assert float_counts(config, schema) == []
    config["selection"]["n_folds"] = 3.0
    config["table2"]["methods"]["RKPCA"] = {"n_components": 0.5}  # a fraction: a number, fine
    config["table3"]["tau"] = 1.0  # a number key given an integral float: fine
    assert float_counts(config, schema) == ["selection.n_folds: 3.0"]
    config["table2"]["methods"]["RKPCA"] = {"n_components": 2.0}  # only the integer branch admits 2.0
    assert "table2.methods.RKPCA.n_components: 2.0" in float_counts(config, schema)


@pytest.mark.pipeline
@pytest.mark.parametrize(
    "path, value",
    [
        (("selection", "n_folds"), 3.0),
        (("selection", "n_rows"), 100.0),
        (("table3", "step"), 3.0),
        (("table2_all", "ours", "n_landmarks"), 100.0),
        (("table2", "seed"), 0.0),
        (("table2", "n_masks"), 2.0),
        (("table1", "n_draws"), 1.0),
        (("table3", "n_seeds"), 1.0),
    ],
)
def test_integer_keys_given_floats_stop_the_dry_run_naming_the_key(tmp_path, path, value):
    config = quick_config()
    node = config
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(config, sort_keys=False))
    proc = subprocess.run(
        [*SNAKEMAKE, "-d", str(tmp_path), "-n", "-c", "1", "--configfile", str(bad)],
        capture_output=True,
        text=True,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert f"{'.'.join(path)}: {value!r}" in out and "invalid config" in out
    assert "Job stats" not in out and "rule run_job" not in out
