"""Table 3 / Figure 1: NRSfM with ground-truth cameras, TNH against the kernel regularizer.

One run = one subsampled CMU mocap sequence, one setting (full data or a fraction of the (frame,
point) observations removed) and one seed of the visibility mask. The protocol of the paper's
Section 4.3:

1. TNH (the trace-norm heuristic, eq. 12) with the ground-truth cameras and tau = 1e-7, solved here
   in its exact-fit limit (see :mod:`nldr.nrsfm._tnh` for why that is the same problem, solved
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
from contextlib import nullcontext
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .. import paper as paper_numbers
from .._threads import single_blas_thread
from .._validation import check_count, check_positive
from ..datasets import load_mocap
from ..nrsfm import e3d, random_visibility_mask, reconstruct, stack_to_rows
from ..paper import paper_frame
from ..plotting import figure1
from ..tables import attach_paper
from ._mocap import (
    WIDTHS,
    MocapExperiment,
    Reconstructions,
    check_sequence,
    every_nth_frame,
    setting_label,
)
from .base import JobOutput

__all__ = ["Table3Run", "run_sequence", "Table3", "Table3Full"]

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
    "energy",
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
        ``converged, n_iter`` (solver iterations: ADMM or the cvxpy solver for TNH, L-BFGS
        iterations summed over the penalty stages for the kernel methods), ``reprojection_rms``
        (root mean square reprojection residual over the observed image coordinates, unit of the
        data), ``energy`` (the kernel methods' final energy (1) at the last rho; NaN for TNH) and
        ``message``.
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


def _tnh_call_options(tnh_options: Mapping | None) -> dict:
    """The pipeline's ``tnh`` mapping as TNH's options of :func:`~nldr.nrsfm.reconstruct`.

    ``solver`` is "ADMM" (default) or a cvxpy conic solver; ``eps`` is a shorthand for SCS's
    ``eps_abs = eps_rel = eps``; any other key is passed to the solver as is (e.g. ``max_iters``).
    """
    options = dict(tnh_options or {})
    solver = str(options.pop("solver", "ADMM")).upper()
    eps = options.pop("eps", None)
    if eps is not None:
        if solver != "SCS":
            raise ValueError(f"tnh_options['eps'] is an SCS tolerance; solver {solver!r} does not take it")
        eps = check_positive(eps, "tnh_options['eps']")
        options.update(eps_abs=eps, eps_rel=eps)
    if solver == "ADMM":
        return {"method": "admm", **options}
    return {"method": "cvxpy", "solver": solver, "solver_options": options}


def _kernel_solve(job, worker: bool = False):
    """One kernel reconstruction -> (result, wall seconds, CPU seconds)."""
    args, options = job
    wall0, cpu0 = time.perf_counter(), time.process_time()
    with single_blas_thread() if worker else nullcontext():  # a pool worker: one thread for all it runs
        res = reconstruct(*args, prior="kernel", **options)
    return res, time.perf_counter() - wall0, time.process_time() - cpu0


def _kernel_solve_in_worker(job):
    return _kernel_solve(job, worker=True)


def run_sequence(
    seq,
    *,
    missing_fraction: float,
    seed: int,
    tau: float | None = None,
    widths=("d_max", "d_med"),
    regularizer: Mapping | None = None,
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
    tau : float > 0, optional
        Trace-norm weight of the kernel regularizer (default: the paper's 1e-4).
    widths : sequence of {"d_max", "d_med"}
        Kernel-width criteria to run, each on the TNH shapes.
    regularizer : mapping, optional
        The kernel method's options of :func:`~nldr.nrsfm.reconstruct` with known cameras: the penalty
        schedule ``rho0, rho_growth, rho_max``, ``center``, the L-BFGS tolerances ``tol, gtol,
        stage_tol`` (:func:`~nldr.regularizer.minimize_regularized`; its ``tol`` is relative to
        ``max(|E|, 1)``, so with the energies of these sequences, about 1e-3, it acts as an absolute
        test a thousand times looser than its nominal value) and ``depth_scale`` (L-BFGS in
        :class:`~nldr.nrsfm.CameraFrameVariables`: same minimisers, far fewer iterations; 100 is the
        measured choice). docs/REPRODUCTION.md#table-3-solver has the measurements.
    tnh_options : mapping, optional
        ``solver`` (default "ADMM"), ``eps`` (SCS's eps_abs = eps_rel) and further options of TNH with
        known cameras (:func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic`; ``ADMM``: its options;
        else a cvxpy conic solver and its ``solver_options``); unset keys take the library's defaults.
    progress : callable, optional
        Receives one line per finished method.
    n_jobs : int, default 1
        Run the width criteria in up to this many worker processes (one BLAS thread each) instead of
        one after another; the results are identical. Pays on long sequences (drink, every frame),
        where one solve gains little from a second BLAS thread (docs/PERFORMANCE.md).

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
    check_sequence(seq, "Table 3")
    frac = check_positive(missing_fraction, "missing_fraction", allow_zero=True)
    if frac >= 1.0:
        raise ValueError(f"missing_fraction must be in [0, 1); got {missing_fraction!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ValueError(f"seed must be an integer; got {seed!r}")
    widths = tuple(widths)
    unknown = [w for w in widths if w not in WIDTHS]
    if unknown or not widths:
        raise ValueError(f"widths must be a non-empty subset of {tuple(WIDTHS)}; got {widths!r}")
    tnh_call = _tnh_call_options(tnh_options)
    n_jobs = check_count(n_jobs, "n_jobs")

    W2d = stack_to_rows(seq.W, dim=2)
    X_gt = stack_to_rows(seq.S, dim=3)
    F, P = W2d.shape[0], W2d.shape[1] // 2
    mask = np.ones((F, P), dtype=bool) if frac == 0 else random_visibility_mask(F, P, frac, int(seed))
    n_obs = max(2 * int(mask.sum()), 1)

    rows, shapes, results = [], {}, {}

    def record(label, rec, wall, cpu, message, energy=np.nan):
        row = {
            "sequence": seq.name,
            "missing_fraction": frac,
            "seed": int(seed),
            "method": label,
            "e3d": e3d(rec.x, X_gt, P),
            "gamma": rec.gamma,
            "seconds": wall,
            "cpu_seconds": cpu,
            "converged": bool(rec.success),
            "n_iter": int(rec.nit),
            "reprojection_rms": float(np.sqrt(rec.reprojection / n_obs)),
            "energy": float(energy),
            "message": message,
        }
        rows.append(row)
        shapes[label] = rec.x
        results[label] = rec.solver
        if progress is not None:
            progress(
                f"{seq.name} {setting_label(frac)} seed={seed} {label:13s} e3d={row['e3d']:.4f} "
                f"{wall:7.1f}s (cpu {cpu:.1f}s) converged={row['converged']} n_iter={row['n_iter']}"
            )

    wall0, cpu0 = time.perf_counter(), time.process_time()
    tnh = reconstruct(W2d, mask, cameras=seq.R, prior="tnh", **tnh_call)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    record("TNH", tnh, wall, cpu, f"{tnh.solver.solver} exact fit: {tnh.message}")

    options = dict(tau=tau, start=tnh, **dict(regularizer or {}))
    jobs = [((W2d, mask), dict(cameras=seq.R, width=width, **options)) for width in widths]
    if n_jobs > 1 and len(jobs) > 1:
        with ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs))) as pool:
            solved = list(pool.map(_kernel_solve_in_worker, jobs))
    else:
        solved = [_kernel_solve(job) for job in jobs]
    for width, (res, wall, cpu) in zip(widths, solved, strict=True):
        record(f"Kernel {width}", res, wall, cpu, res.message, res.fun)

    return Table3Run(
        rows=pd.DataFrame(rows, columns=_ROW_COLUMNS),
        shapes=shapes,
        mask=mask,
        ground_truth=X_gt,
        results=results,
    )


class Table3(MocapExperiment):
    """Table 3 and Figure 1: NRSfM with ground-truth cameras (paper Section 4.3)."""

    name = "table3"
    title = "NRSfM with ground-truth cameras: TNH against the kernel regularizer"
    in_paper = True
    paper = paper_numbers.TABLE3
    notebook = "table3_nrsfm"
    figures = ("fig1",)
    figure_captions = {
        "fig1": (
            "Figure 1: sample frames with 50 % of the 2D points missing. Red wire-frame: ground truth; blue "
            "dots: the kernel regularizer (d_med); black crosses: TNH. Circles mark points observed in that "
            "frame, squares the missing ones."
        )
    }

    def resources(self, config, job):
        return {"mem_mb": 2000, "runtime": 30}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        seq = self.load(job, settings, data_dir, progress)
        run = run_sequence(
            seq,
            missing_fraction=job.params["missing_fraction"],
            seed=job.params["seed"],
            tau=settings["tau"],
            widths=tuple(settings["widths"]),
            regularizer=settings["regularizer"],
            tnh_options=settings["tnh"],
            progress=progress,
            n_jobs=threads,  # width criteria in parallel when the job has 2 threads (drink, every frame)
        )
        recon = Reconstructions(shapes=run.shapes, mask=run.mask, ground_truth=run.ground_truth)
        return JobOutput(rows=run.rows, arrays=recon.to_arrays())

    def caption(self, config):
        s = self.settings(config)
        return (
            f"Table 3: NRSfM with ground-truth cameras on CMU mocap ({every_nth_frame(s['step'])}), "
            f"normalised mean 3D error e3D of the trace-norm heuristic (TNH, linear) and of the kernel "
            f"regularizer (tau = {s['tau']:g}) with the d_max and d_med kernel widths, with full data and "
            f"with {s['missing_fraction']:.0%} of the 2D points missing (mean ± sd over {s['n_seeds']} "
            "seeded masks). Paper in parentheses."
        )

    def draw(self, figure, runs, arrays, data_dir):
        if figure != "fig1":
            return super().draw(figure, runs, arrays, data_dir)
        # one reconstruction per sequence: its first missing-data job, else its full-data job
        chosen = {}
        for job_id in sorted(arrays):
            seq, setting = job_id.split("_")[:2]
            if seq not in chosen or (setting == "missing" and "_missing_" not in chosen[seq]):
                chosen[seq] = job_id
        recons = {seq: Reconstructions.from_arrays(arrays[job_id]) for seq, job_id in chosen.items()}
        mocap = {seq: load_mocap(seq, data_dir) for seq in recons}
        bones, total = {s: m.bones for s, m in mocap.items()}, {s: m.n_frames for s, m in mocap.items()}
        return figure1(recons, bones, total_frames=total)


class Table3Full(Table3):
    """Table 3 on every frame (not in the paper; speed and scale), beside Table 3's every 10th frame."""

    name = "table3_full"
    title = "Table 3 on every frame (not in the paper)"
    in_paper = False
    notebook = None
    figures = ()
    figure_captions = {}
    inherits = "table3"
    gathers_with = ("table3",)

    def threads(self, config, job):
        return 2 if job.params["sequence"] == "drink" else 1  # 1102 x 1102 kernels: BLAS on 2 cores

    def resources(self, config, job):
        return {"mem_mb": 4000, "runtime": 60}

    def table(self, runs, config, others):
        """Each method twice: "<method>, every frame" (this experiment's runs) and "<method>, every
        10th frame" (Table 3's), the paper's numbers beside the latter (the paper ran only those)."""
        published = paper_frame(self.paper)
        full, sub = self.summarise(runs), self.summarise(others["table3"])
        full_label = every_nth_frame(self.settings(config)["step"])
        sub_label = every_nth_frame(config["table3"]["step"])
        paired = []
        for method in dict.fromkeys(sub["method"]):
            paired.append(attach_paper(full[full["method"] == method], published.iloc[:0]))
            paired[-1]["method"] = f"{method}, {full_label}"
            paired.append(attach_paper(sub[sub["method"] == method], published))
            paired[-1]["method"] = f"{method}, {sub_label}"
        table = pd.concat(paired, ignore_index=True)
        order = {s: i for i, s in enumerate(dict.fromkeys(sub["setting"]))}
        return table.sort_values("setting", key=lambda s: s.map(order), kind="stable").reset_index(drop=True)

    def caption(self, config):
        s, t3 = self.settings(config), config["table3"]
        return (
            f"Table 3 on {every_nth_frame(s['step'])} (not in the paper) beside "
            f"{every_nth_frame(t3['step'])}: e3D with ground-truth cameras, TNH (exact fit, "
            f"{s['tnh']['solver']}) and the kernel regularizer; paper (every 10th frame) in parentheses."
        )
