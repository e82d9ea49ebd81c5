"""Put known faults into a copy of the project one at a time and report which the test suite catches.

Each mutant is a one-line change that a careless edit could make (issue 19's list, and more). For each,
the tracked files are copied to a scratch folder, the change is applied (it must match exactly once),
and the tests that guard that behaviour run there (``-x``, stopping at the first failure). A mutant is
*caught* when those tests fail. Run with ``make mutants`` (a few minutes; the pipeline mutants run
Snakemake on the quick protocol). Not collected by pytest (the file name does not start with test_).

Usage::

    python tests/mutants.py            # every mutant
    python tests/mutants.py atomic     # those whose name contains "atomic"
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutant:
    name: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


MUTANTS = [
    Mutant(
        "atomic writes: CSV written in place",
        "workflow/scripts/_pipeline.py",
        '    with atomic_path(path) as tmp:\n        frame.to_csv(tmp, index=False, float_format="%.10g")',
        '    frame.to_csv(path, index=False, float_format="%.10g")',
        ("tests/test_atomic_writes.py",),
    ),
    Mutant(
        "atomic writes: a job script bypasses the helpers",
        "workflow/scripts/run_job.py",
        "write_csv(sm.output.table, results.rows)",
        "results.rows.to_csv(sm.output.table, index=False)",
        ("tests/test_atomic_writes.py",),
    ),
    Mutant(
        "fetch trusts a file already in place",
        "src/nldr/datasets.py",
        "    if dest.is_file():\n        return verify(dest, relpath)",
        "    if dest.is_file():\n        return dest",
        ("tests/test_datasets.py",),
    ),
    Mutant(
        "data not verified before the jobs",
        "workflow/rules/data.smk",
        "    verify_present(DATA_DIR)",
        "    pass",
        (
            "tests/test_reliability.py::test_data_corrupted_after_a_good_run_stops_the_rerun_with_every_result_intact",
        ),
    ),
    Mutant(
        "MaskedLeastSquares accepts non-finite observed data",
        "src/nldr/_validation.py",
        "    if not np.all(np.isfinite(W[mask_arr])):",
        "    if False:",
        ("tests/test_reliability.py::test_non_finite_observed_data_is_refused_by_every_data_term",),
    ),
    Mutant(
        "schema: free-form keys under methods.Ours",
        "workflow/schemas/config.schema.yaml",
        "          Ours:                   # parameters of nldr.impute.KernelRegularizerImputer"
        " (gamma: table2.gamma)\n            type: object\n            additionalProperties: false",
        "          Ours:\n            type: object",
        ("tests/test_schema.py",),
    ),
    Mutant(
        "isolation guard off by default",
        "src/nldr/_options.py",
        "    isolation_guard: bool = True\n",
        "    isolation_guard: bool = False\n",
        ("tests/test_regularizer.py::test_the_isolation_guard_is_on_by_default",),
    ),
    Mutant(
        "scale: stopping tests on absolute values (unit 1)",
        "src/nldr/regularizer.py",
        "    scale = float(np.sqrt(float(rho0))) if opts.scale is None else opts.scale",
        "    scale = 1.0",
        ("tests/test_reliability_scale.py::test_equivalent_problems_take_the_same_iterates_at_every_scale",),
    ),
    Mutant(
        "scale: gradient test on the unscaled gradient",
        "src/nldr/_reduced.py",
        "        value, grad = value / unit, grad * (scale / unit)",
        "        value = value / unit",
        ("tests/test_reliability_scale.py::test_equivalent_problems_take_the_same_iterates_at_every_scale",),
    ),
    Mutant(
        "a solve that does nothing says converged",
        "src/nldr/_penalty.py",
        "    unchanged = np.array_equal(S, S_start)",
        "    unchanged = False",
        ("tests/test_reliability_scale.py::test_data_in_raw_units_with_unit_parameters_is_not_called_converged",),
    ),
    Mutant(
        "callback stops only when it returns the object True",
        "src/nldr/_penalty.py",
        "_stops(callback(info))",
        "callback(info) is True",
        ("tests/test_reliability_scale.py::test_a_callback_stops_on_any_true_value",),
    ),
    Mutant(
        "penalty schedule without a stage bound",
        "src/nldr/_schedule.py",
        "    if not expected < MAX_PENALTY_STAGES:",
        "    if False:",
        ("tests/test_reliability_scale.py::test_the_number_of_penalty_stages_is_bounded_before_the_list_is_built",),
    ),
    Mutant(
        "integer config keys given as floats pass",
        "src/nldr/experiments/base.py",
        '        found.append(f"{path}: {config!r}")',
        "        pass",
        ("tests/test_reliability_scale.py::test_float_counts_names_every_integer_key_written_as_a_float",),
    ),
    Mutant(
        "sample sd replaced by population sd",
        "src/nldr/experiments/base.py",
        "SD_DDOF = 1",
        "SD_DDOF = 0",
        ("tests/test_experiments.py",),
    ),
    Mutant(
        "imputers solve in the data's units (standardisation dropped)",
        "src/nldr/impute/_base.py",
        "self.shift_, self.scale_ = _standardisation(W, mask)",
        "self.shift_, self.scale_ = np.zeros(W.shape[1]), np.ones(W.shape[1])",
        ("tests/test_reliability_units.py::test_every_estimator_is_unit_free_per_column",),
    ),
    Mutant(
        "SoftImpute's first stopping test absolute again",
        "src/nldr/_baselines/peers.py",
        "size = float(np.sum(Z * Z)) or float(np.sum(Z_new * Z_new))",
        "size = float(np.sum(Z * Z)) or 1.0",
        ("tests/test_reliability_units.py::test_soft_impute_on_small_units_takes_the_same_iterates",),
    ),
    Mutant(
        "the regularizer's hold-out search scores the data's units",
        "src/nldr/impute/_regularizer.py",
        "chosen = tune(self, Z, mask, grid)",
        "chosen = tune(self, W, mask, grid)",
        ("tests/test_reliability_units.py::test_the_regularizers_search_is_not_decided_by_a_columns_units",),
    ),
    Mutant(
        "a mean fill is called converged",
        "src/nldr/impute/_base.py",
        "        self._check_moved(W, mask)\n",
        "",
        (
            "tests/test_reliability_units.py::test_kernel_baselines_in_raw_units_that_do_not_move_say_so",
            "tests/test_reliability_units.py::test_the_papers_settings_on_other_units_warn_instead_of_returning_the_mean_fill_silently",
            "tests/test_reliability_units.py::test_a_lam_that_removes_everything_is_a_mean_fill_not_a_convergence",
        ),
    ),
    Mutant(
        "a search no better than the column means is not reported",
        "src/nldr/impute/_tuning.py",
        "if errors is None or errors[0] < errors[1]:",
        "if True:",
        ("tests/test_reliability_units.py::test_a_search_no_better_than_the_column_means_says_so",),
    ),
    Mutant(
        "imputer: fit_transform returns the denoised estimate",
        "src/nldr/impute/_base.py",
        "        if not self._denoises():\n            X_hat = np.where(mask, W, X_hat)\n",
        "",
        ("tests/test_reliability_consistency.py",),
    ),
    Mutant(
        "imputer: copies of a training row keep their own estimates",
        "src/nldr/impute/_base.py",
        "    if not copies:\n        return X_hat",
        "    if True:\n        return X_hat",
        ("tests/test_reliability_consistency.py",),
    ),
    Mutant(
        "regularizer: transform denoises new rows without the option",
        "src/nldr/impute/_regularizer.py",
        "        return X_hat if self.denoise else np.where(mask, W, X_hat)",
        "        return X_hat",
        ("tests/test_reliability_consistency.py",),
    ),
    Mutant(
        "robust PCA: transform ignores denoise",
        "src/nldr/impute/_linear.py",
        "robust=True, denoise=self.denoise",
        "robust=True, denoise=False",
        ("tests/test_reliability_consistency.py",),
    ),
    Mutant(
        "regularizer: the search sees the rows in the order given",
        "src/nldr/impute/_tuning.py",
        "search.fit(np.where(mask, W, np.nan)[order])",
        "search.fit(np.where(mask, W, np.nan))",
        ("tests/test_reliability_consistency.py",),
    ),
    Mutant(
        "regularizer: the search's folds follow random_state",
        "src/nldr/impute/_regularizer.py",
        "(rows in canonical order) only.\"\"\"\n        return 0",
        "(rows in canonical order) only.\"\"\"\n"
        "        return int(check_random_state(self.random_state).randint(np.iinfo(np.int32).max))",
        ("tests/test_reliability_consistency.py",),
    ),
    Mutant(
        "regularizer: the default's landmarks drawn at random",
        "src/nldr/impute/_defaults.py",
        'AUTO_LANDMARKS, AUTO_LANDMARK_RULE, AUTO_STAGE_TOL = 150, "pivoted", 1e-5',
        'AUTO_LANDMARKS, AUTO_LANDMARK_RULE, AUTO_STAGE_TOL = 150, "random", 1e-5',
        ("tests/test_reliability_consistency.py",),
    ),
    Mutant(
        "regularizer: the default starts from the mean at every size",
        "src/nldr/impute/_regularizer.py",
        'return "knn" if self.method == "auto" and n >= AUTO_KNN_MIN_ROWS else "mean"',
        'return "mean"',
        ("tests/test_impute.py::test_auto_method_runs_every_stage_on_pivoted_landmarks_above_its_threshold",),
    ),
    Mutant(
        "regularizer: tol='auto' is the strict tolerance on every path",
        "src/nldr/impute/_regularizer.py",
        'options["tol"] = AUTO_NYSTROEM_TOL if is_auto(self.tol) else options["tol"]',
        "pass",
        ("tests/test_impute.py::test_tol_auto_is_looser_on_the_approximate_path_only",),
    ),
    Mutant(
        "regularizer: the search runs at every size",
        "src/nldr/impute/_regularizer.py",
        "TUNE_MIN_ROWS <= W.shape[0] < TUNE_MAX_ROWS",
        "TUNE_MIN_ROWS <= W.shape[0]",
        ("tests/test_reliability_consistency.py",),
    ),
]


def _copy_tracked(dest: Path) -> None:
    files = (
        subprocess.run(["git", "-C", str(REPO), "ls-files", "-z"], capture_output=True, check=True)
        .stdout.decode()
        .split("\0")
    )
    for rel in filter(None, files):
        src = REPO / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)


def run(mutant: Mutant) -> tuple[bool, float, str]:
    """Apply ``mutant`` in a scratch copy and run its tests; (caught, seconds, last line of output).

    Caught means a test failed (pytest's exit code 1); any other failure of the run is an error of the
    mutant's definition, not a catch."""
    with tempfile.TemporaryDirectory(prefix="nldr-mutant-") as tmp:
        work = Path(tmp)
        _copy_tracked(work)
        target = work / mutant.path
        text = target.read_text()
        if text.count(mutant.old) != 1:
            raise SystemExit(
                f"mutant {mutant.name!r}: its text occurs {text.count(mutant.old)} times in {mutant.path}"
            )
        target.write_text(text.replace(mutant.old, mutant.new))
        env = {**os.environ, "PYTHONPATH": str(work / "src"), "MPLBACKEND": "Agg"}
        start = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *mutant.tests],
            cwd=work,
            env=env,
            capture_output=True,
            text=True,
        )
        lines = [line for line in proc.stdout.splitlines() if line.strip()]
        last = lines[-1] if lines else proc.stderr[-200:]
        if proc.returncode not in (0, 1):  # 2-5: interrupted, internal error, usage error, no tests
            raise SystemExit(f"mutant {mutant.name!r}: the tests did not run properly ({last})")
        return proc.returncode == 1, time.perf_counter() - start, last


def main(argv: list[str]) -> int:
    chosen = [m for m in MUTANTS if not argv or any(a in m.name for a in argv)]
    missed = 0
    print(f"{'mutant':55s} {'outcome':8s} {'seconds':>7s}  tests' last line")
    for mutant in chosen:
        caught, seconds, last = run(mutant)
        missed += not caught
        print(f"{mutant.name:55s} {'caught' if caught else 'MISSED':8s} {seconds:7.1f}  {last}", flush=True)
    print(f"{len(chosen) - missed} of {len(chosen)} mutants caught")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
