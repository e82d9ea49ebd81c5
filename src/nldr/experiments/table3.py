"""Table 3 / Figure 1: NRSfM with ground-truth cameras, TNH against the kernel regularizer.

One run = one subsampled CMU mocap sequence, one setting (full data or a fraction of the (frame,
point) observations removed) and one seed of the visibility mask. The protocol of the paper's
Section 4.3:

1. TNH (the trace-norm heuristic, eq. 12) with the ground-truth cameras and tau = 1e-7, solved here
   in its exact-fit limit (see :mod:`nldr.nrsfm.tnh` for why that is the same problem, solved
   soundly); its reconstruction is the linear baseline and the initial estimate of step 2.
2. For each kernel-width criterion (``d_max``: the most distant pair of TNH shapes gets kernel value
   exp(-9/2); ``d_med``: the median pair gets 1/2), the regularizer of Algorithm 1 with the
   orthographic reprojection data term, the ground-truth cameras and tau = 1e-4, from the TNH shapes.
3. e3D of every reconstruction against the ground truth (:func:`nldr.nrsfm.e3d`).

The data stay in their original units (the paper's tau assume them). The penalty schedule and the
kernel centring are choices the paper leaves open; docs/REPRODUCTION.md#table-3-solver gives the
measurements behind the defaults here.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from .._validation import check_count, check_positive
from ..kernels import d_max_width, d_med_width
from ..nrsfm import OrthographicReprojection, e3d, random_visibility_mask, stack_to_rows, trace_norm_heuristic
from ..regularizer import minimize_regularized

__all__ = ["METHODS", "WIDTHS", "SEQUENCES", "Table3Run", "setting_label", "run_sequence", "summarise"]

#: Kernel-width criteria: name -> gamma of the RBF kernel from the TNH shapes (samples as rows).
WIDTHS: dict[str, Callable[[np.ndarray], float]] = {"d_max": d_max_width, "d_med": d_med_width}
#: Method labels in the paper's column order.
METHODS = ("TNH", "Kernel d_max", "Kernel d_med")
#: The paper's sequences, in its row order.
SEQUENCES = ("drink", "pickup", "yoga", "stretch")

_ROW_COLUMNS = [
    "sequence",
    "missing_fraction",
    "seed",
    "method",
    "e3d",
    "gamma",
    "seconds",
    "cpu_seconds",
    "converged",
    "n_iter",
    "reprojection_rms",
    "message",
]


@dataclass
class Table3Run:
    """Outcome of :func:`run_sequence` for one (sequence, setting, seed).

    Attributes
    ----------
    rows : DataFrame
        One row per method (``"TNH"``, ``"Kernel d_max"``, ``"Kernel d_med"``): ``sequence,
        missing_fraction, seed, method, e3d, gamma`` (NaN for TNH), ``seconds`` (wall) and
        ``cpu_seconds`` of that method alone (the kernel methods exclude the TNH they start from),
        ``converged, n_iter`` (solver iterations: SCS for TNH, L-BFGS or sweeps summed over the
        penalty stages for the kernel methods), ``reprojection_rms`` (root mean square reprojection
        residual over the observed image coordinates, unit of the data) and ``message``.
    shapes : dict
        Method -> reconstruction, array (F, 3P) (shapes as rows, unit of the data).
    mask : bool array, shape (F, P)
        True where the point was observed (all True for full data).
    ground_truth : array, shape (F, 3P)
        The sequence's ground-truth shapes as rows.
    results : dict
        Method -> the solver's result object (:class:`~nldr.nrsfm.TNHResult` or
        :class:`~nldr.regularizer.RegularizerResult`) with its histories, for convergence plots.
    """

    rows: pd.DataFrame
    shapes: dict[str, np.ndarray]
    mask: np.ndarray
    ground_truth: np.ndarray
    results: dict = field(default_factory=dict)


def setting_label(missing_fraction: float) -> str:
    """``"full"`` for 0, else ``"missing<percent>"`` (``0.5 -> "missing50"``), as in :mod:`nldr.paper`."""
    return "full" if missing_fraction == 0 else f"missing{round(100 * float(missing_fraction)):d}"


def _tnh_call_options(tnh_options: Mapping | None) -> tuple[str, dict]:
    """Split the pipeline's ``tnh`` mapping into (solver, solver_options).

    ``eps`` is a shorthand for SCS's ``eps_abs = eps_rel = eps``; any other key is passed to the
    solver as is (e.g. ``max_iters``).
    """
    options = dict(tnh_options or {})
    solver = str(options.pop("solver", "SCS")).upper()
    eps = options.pop("eps", None)
    if eps is not None:
        if solver != "SCS":
            raise ValueError(f"tnh_options['eps'] is an SCS tolerance; solver {solver!r} does not take it")
        eps = check_positive(eps, "tnh_options['eps']")
        options.update(eps_abs=eps, eps_rel=eps)
    return solver, options


def _kernel_solve(job, worker: bool = False):
    """One kernel-regularizer solve -> (gamma, result, wall seconds, CPU seconds)."""
    data_term, X0, gamma, options = job
    wall0, cpu0 = time.perf_counter(), time.process_time()
    with threadpool_limits(1 if worker else None):
        res = minimize_regularized(data_term, X0, gamma=gamma, **options)
    return gamma, res, time.perf_counter() - wall0, time.process_time() - cpu0


def _kernel_solve_in_worker(job):
    return _kernel_solve(job, worker=True)


def _check_sequence(seq):
    for attr in ("name", "W", "S", "R"):
        if not hasattr(seq, attr):
            raise ValueError(f"seq must be a MocapSequence (nldr.datasets.load_mocap); it has no {attr!r}")
    if seq.R is None:
        raise ValueError(f"sequence {seq.name!r} has no ground-truth cameras (R is None); Table 3 needs them")


def run_sequence(
    seq,
    *,
    missing_fraction: float,
    seed: int,
    tau: float = 1e-4,
    widths=("d_max", "d_med"),
    rho0: float = 1e-3,
    rho_growth: float = 10.0,
    rho_max: float = 10.0,
    center: bool = False,
    method: str = "reduced",
    max_inner: int | None = None,
    tnh_options: Mapping | None = None,
    progress: Callable[[str], None] | None = None,
    n_jobs: int = 1,
) -> Table3Run:
    """TNH and the kernel regularizer (one per width criterion) on one sequence and mask.

    Parameters
    ----------
    seq : MocapSequence
        An already subsampled sequence with ground-truth cameras (``load_mocap(name).subsample(10)``),
        in the original units.
    missing_fraction : float in [0, 1)
        Fraction of (frame, point) observations removed; 0 means all observed (no mask is drawn).
    seed : int
        Seed of :func:`~nldr.nrsfm.random_visibility_mask` (recorded, unused for full data).
    tau : float > 0, default 1e-4
        Trace-norm weight of the kernel regularizer (paper).
    widths : sequence of {"d_max", "d_med"}
        Kernel-width criteria to run, each on the TNH shapes.
    rho0, rho_growth, rho_max : float
        Penalty schedule of :func:`~nldr.regularizer.minimize_regularized`; the defaults (1e-3 to 10,
        x10) are the ones measured in docs/REPRODUCTION.md#table-3-solver.
    center : bool, default False
        Double-centre the kernel.
    method : {"reduced", "alternation"}, default "reduced"
        Inner solver of the regularizer.
    max_inner : int, optional
        Per-stage iteration limit of the regularizer (its default when None).
    tnh_options : mapping, optional
        ``solver`` (default "SCS"), ``eps`` (SCS's eps_abs = eps_rel) and further solver options for
        :func:`~nldr.nrsfm.trace_norm_heuristic` (``ADMM``: its options; else a cvxpy conic solver
        and its ``solver_options``); unset keys take the library's defaults.
    progress : callable, optional
        Receives one line per finished method.
    n_jobs : int, default 1
        Run the width criteria in up to this many worker processes (one BLAS thread each) instead of
        one after another; the results are identical. Pays on long sequences (drink, every frame:
        two 5-minute solves), where one solve gains little from a second BLAS thread.

    Returns
    -------
    Table3Run
        Per-method rows, the reconstructions, the mask and the ground truth.

    Raises
    ------
    ValueError
        If ``seq`` lacks cameras or an argument is out of range (the message names it).
    nldr.nrsfm.TNHSolveError
        If the conic solver fails on TNH.
    """
    _check_sequence(seq)
    frac = check_positive(missing_fraction, "missing_fraction", allow_zero=True)
    if frac >= 1.0:
        raise ValueError(f"missing_fraction must be in [0, 1); got {missing_fraction!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ValueError(f"seed must be an integer; got {seed!r}")
    widths = tuple(widths)
    unknown = [w for w in widths if w not in WIDTHS]
    if unknown or not widths:
        raise ValueError(f"widths must be a non-empty subset of {tuple(WIDTHS)}; got {widths!r}")
    solver, solver_options = _tnh_call_options(tnh_options)
    n_jobs = check_count(n_jobs, "n_jobs")
    regularizer_options = dict(
        tau=check_positive(tau, "tau"),
        center=bool(center),
        method=method,
        rho0=rho0,
        rho_growth=rho_growth,
        rho_max=rho_max,
        max_inner=max_inner,
    )

    W2d = stack_to_rows(seq.W, dim=2)
    X_gt = stack_to_rows(seq.S, dim=3)
    F, P = W2d.shape[0], W2d.shape[1] // 2
    mask = np.ones((F, P), dtype=bool) if frac == 0 else random_visibility_mask(F, P, frac, int(seed))
    data_term = OrthographicReprojection(W2d, seq.R, mask)
    n_obs = max(data_term.n_residuals, 1)

    rows, shapes, results = [], {}, {}

    def record(label, X, gamma, wall, cpu, converged, n_iter, message, result):
        r = data_term.residuals(X)
        row = {
            "sequence": seq.name,
            "missing_fraction": frac,
            "seed": int(seed),
            "method": label,
            "e3d": e3d(X, X_gt, P),
            "gamma": gamma,
            "seconds": wall,
            "cpu_seconds": cpu,
            "converged": bool(converged),
            "n_iter": int(n_iter),
            "reprojection_rms": float(np.sqrt(r @ r / n_obs)),
            "message": message,
        }
        rows.append(row)
        shapes[label] = X
        results[label] = result
        if progress is not None:
            progress(
                f"{seq.name} {setting_label(frac)} seed={seed} {label:13s} e3d={row['e3d']:.4f} "
                f"{wall:7.1f}s (cpu {cpu:.1f}s) converged={row['converged']} n_iter={row['n_iter']}"
            )

    wall0, cpu0 = time.perf_counter(), time.process_time()
    if solver == "ADMM":
        tnh = trace_norm_heuristic(W2d, seq.R, mask, method="admm", **solver_options)
    else:  # a cvxpy conic solver
        tnh = trace_norm_heuristic(
            W2d, seq.R, mask, method="cvxpy", solver=solver, solver_options=solver_options
        )
    record(
        "TNH",
        tnh.x,
        np.nan,
        time.perf_counter() - wall0,
        time.process_time() - cpu0,
        tnh.success,
        tnh.nit,
        f"{tnh.solver} exact fit: {tnh.message}",
        tnh,
    )

    jobs = [(data_term, tnh.x, WIDTHS[width](tnh.x), regularizer_options) for width in widths]
    if n_jobs > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs))) as pool:
            solved = list(pool.map(_kernel_solve_in_worker, jobs))
    else:
        solved = [_kernel_solve(job) for job in jobs]
    for width, (gamma, res, wall, cpu) in zip(widths, solved, strict=True):
        record(f"Kernel {width}", res.S, gamma, wall, cpu, res.converged, res.n_inner, res.message, res)

    return Table3Run(
        rows=pd.DataFrame(rows, columns=_ROW_COLUMNS),
        shapes=shapes,
        mask=mask,
        ground_truth=X_gt,
        results=results,
    )


def _sequence_order(names) -> list[str]:
    known = [s for s in SEQUENCES if s in set(names)]
    return known + sorted(set(names) - set(SEQUENCES))


def _stats(per_seed: pd.Series) -> dict[str, float]:
    """Mean, sample sd (NaN for one seed), min, max and count of per-seed errors."""
    n = len(per_seed)
    return {
        "e3d": float(per_seed.mean()) if n else np.nan,
        "e3d_sd": float(per_seed.std(ddof=1)) if n > 1 else np.nan,
        "e3d_min": float(per_seed.min()) if n else np.nan,
        "e3d_max": float(per_seed.max()) if n else np.nan,
        "n_seeds": float(n),
    }


def summarise(runs: pd.DataFrame) -> pd.DataFrame:
    """Aggregate :func:`run_sequence` rows into Table 3's tidy rows (setting, method, metric, value).

    Settings are ``"<Sequence> <full|missing50>"`` as in :data:`nldr.paper.TABLE3`, plus
    ``"Mean <full|missing50>"``. Per sequence, setting and method: ``e3d`` is the mean over seeds,
    ``e3d_sd`` the sample standard deviation over seeds (NaN with one seed), ``e3d_min``,
    ``e3d_max`` and ``n_seeds``. The Mean rows follow the paper (the mean over sequences): ``e3d``
    is the mean over the sequences of their per-sequence means; the spread metrics treat the
    across-sequence mean of one seed as one replicate, over the seeds every sequence ran
    (``n_seeds`` counts them); ``n_sequences`` says how many sequences entered the mean.
    Timings stay in the run frames: a table must not change between reruns.
    """
    missing = set(_ROW_COLUMNS[:5]) - set(runs.columns)
    if missing:
        raise ValueError(f"runs lacks columns {sorted(missing)}; pass the rows of run_sequence")
    methods = [m for m in METHODS if m in set(runs["method"])]
    methods += sorted(set(runs["method"]) - set(METHODS))
    sequences = _sequence_order(runs["sequence"].unique())
    fractions = sorted(runs["missing_fraction"].unique())
    rows = []
    for frac in fractions:
        label = setting_label(frac)
        for seq in sequences:
            for method in methods:
                group = runs[
                    (runs["missing_fraction"] == frac)
                    & (runs["sequence"] == seq)
                    & (runs["method"] == method)
                ]
                if group.empty:
                    continue
                per_seed = group.groupby("seed")["e3d"].mean()
                for metric, value in _stats(per_seed).items():
                    rows.append((f"{seq.capitalize()} {label}", method, metric, value))
        for method in methods:
            group = runs[(runs["missing_fraction"] == frac) & (runs["method"] == method)]
            if group.empty:
                continue
            # (seed x sequence) table of errors; the Mean's value averages each sequence over its seeds
            grid = group.pivot_table(index="seed", columns="sequence", values="e3d", aggfunc="mean")
            stats = _stats(grid.dropna(axis=0, how="any").mean(axis=1))
            stats["e3d"] = float(grid.mean(axis=0).mean())
            stats["n_sequences"] = float(grid.shape[1])
            for metric, value in stats.items():
                rows.append((f"Mean {label}", method, metric, value))
    out = pd.DataFrame(rows, columns=["setting", "method", "metric", "value"])
    return _paper_order(out)


def _paper_order(table: pd.DataFrame) -> pd.DataFrame:
    """Rows by sequence (paper order, Mean last), full before missing, then method and metric order."""
    settings = list(dict.fromkeys(table["setting"]))
    names = list(dict.fromkeys(s.split(" ", 1)[0] for s in settings))
    names = [n for n in names if n != "Mean"] + (["Mean"] if "Mean" in names else [])
    kinds = sorted({s.split(" ", 1)[1] for s in settings}, key=lambda k: (k != "full", k))
    order = [f"{n} {k}" for n in names for k in kinds if f"{n} {k}" in settings]
    key = {s: i for i, s in enumerate(order)}
    return (
        table.assign(_k=table["setting"].map(key), _i=np.arange(len(table)))
        .sort_values(["_k", "_i"], kind="stable")
        .drop(columns=["_k", "_i"])
        .reset_index(drop=True)
    )
