"""Robust NRSfM (not in the paper): Table 3's known-camera setting with gross tracking errors.

One job is one CMU mocap sequence (Table 3's frame subsampling, ground-truth cameras, every point
observed) and one seed. The seed displaces, for every share c, that share of the observed image
coordinates by the robust-completion experiment's rule (:func:`nldr.experiments._robust.gross_corruption`
on the tracks W (F, 2P): a random sign times 3-6 standard deviations of that coordinate's track; the
shares are nested). Each method sees only the corrupted tracks; rows per (share, job):

- ``TNH``: the exact-fit trace-norm heuristic (Table 3's linear baseline), least squares in the limit;
- ``TNH (robust)``: :func:`nldr.nrsfm._admm.robust_trace_norm_heuristic`, tau ||X||_* + l1
  reprojection error, tau = ``tau_factor`` x sqrt(max(F, 3P)) (the robust-PCA scaling of Candes et
  al.: the l1 term sums F x 2P entries, the nuclear norm at most min(F, 3P) singular values);
- ``Kernel (LS)``: Table 3's kernel method (tau, width rule and schedule of Table 3) from the TNH shapes;
- ``Kernel (Huber)``: the same regularizer with :class:`nldr.data_terms.Huber` around the reprojection
  term, started from the robust TNH shapes (its width from them too). delta = ``delta_factor`` x the
  MAD scale (:func:`nldr.model_selection.robust_scale`) of the robust start's residuals that are not
  zero (l1 leaves most inlier residuals exactly zero, so the MAD of all of them is 0), and the
  kernel's tau carries the robust start's balance of data and regularizer over (see
  :func:`huber_kernel_parameters`). No ground truth enters any choice.

The metric is e3D against the ground truth (:func:`nldr.nrsfm.e3d`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd

from ..kernels import rbf_kernel
from ..model_selection import robust_scale
from ..nrsfm import OrthographicReprojection, e3d, reconstruct, stack_to_rows
from ._mocap import SEQUENCES, WIDTHS, MocapExperiment, Reconstructions, every_nth_frame
from ._robust import gross_corruption
from .base import Job, JobOutput, summary_stats

__all__ = ["METHODS", "RobustNRSfM", "huber_kernel_parameters", "robust_tnh_tau", "run_displaced"]

#: Row order of the table.
METHODS = ("TNH", "TNH (robust)", "Kernel (LS)", "Kernel (Huber)")


def robust_tnh_tau(shape: tuple[int, int], tau_factor: float) -> float:
    """tau of the robust TNH for shapes of ``shape`` (F, 3P): ``tau_factor * sqrt(max(F, 3P))``."""
    return float(tau_factor) * float(np.sqrt(max(shape)))


def huber_kernel_parameters(
    term, X_start, tau_start: float, gamma: float, delta_factor: float, balance: float
):
    """(delta, tau) of the Huber kernel method started from a robust TNH solution, from the tracks alone.

    delta is ``delta_factor`` x :func:`~nldr.model_selection.robust_scale` of the start's non-zero
    residuals. For residuals beyond delta the Huber term is 2 delta |r| (l1 scaled by 2 delta), so the
    kernel's tau is set to carry the robust start's weighting over: the start minimised
    ``l1 + tau_start ||X||_*``; at the start the kernel regularizer ``sum sqrt(eig K)`` gets the same
    weight relative to l1 when ``tau / (2 delta) = balance * tau_start ||X||_* / sum sqrt(eig K)``.

    Returns
    -------
    delta : float
        Huber threshold (unit of the tracks).
    tau : float
        Weight of the kernel regularizer (unit of the tracks squared).
    """
    r = term.residuals(X_start)
    scale_tracks = float(np.sqrt(np.mean(r**2))) if r.size else 1.0
    nonzero = r[np.abs(r) > 1e-9 * max(scale_tracks, 1e-300)]
    delta = float(delta_factor) * robust_scale(nonzero if nonzero.size >= 2 else r)
    K = rbf_kernel(X_start, gamma)
    spectrum = float(np.sqrt(np.clip(np.linalg.eigvalsh(K), 0.0, None)).sum())
    nuclear = float(np.linalg.svd(X_start, compute_uv=False).sum())
    tau = 2.0 * delta * float(balance) * tau_start * nuclear / spectrum
    return delta, tau


def run_displaced(
    W2d,
    R,
    X_gt,
    *,
    shares,
    seed: int,
    settings: Mapping,
    name: str = "sequence",
    progress: Callable[[str], None] | None = None,
) -> tuple[pd.DataFrame, dict[str, dict]]:
    """The four methods on clean tracks displaced by every share of ``shares``.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Clean image tracks as rows (every point observed).
    R : array, shape (F, 2, 3)
        Ground-truth cameras.
    X_gt : array, shape (F, 3P)
        Ground-truth shapes as rows (for e3D only).
    shares : sequence of float in [0, 0.5)
        Shares of the image coordinates displaced (nested).
    seed : int
        Seed of the displacement.
    settings : mapping
        The ``robust_nrsfm`` config block (without its enumerating keys).
    name : str
        Sequence name for the rows.
    progress : callable, optional
        Receives one line per method.

    Returns
    -------
    rows : DataFrame
        ``sequence, displaced, seed, method, e3d, seconds, converged, n_iter, delta, tau, n_displaced``.
    arrays : dict
        share -> :class:`~nldr.experiments._mocap.Reconstructions` (shapes per method, the displaced
        coordinates as ``extra["displaced"]`` (F, 2P)).
    """
    say = progress or (lambda line: None)
    W2d = np.asarray(W2d, dtype=np.float64)
    F, P = W2d.shape[0], W2d.shape[1] // 2
    mask = np.ones((F, P), dtype=bool)
    sd = settings["displacement_sd"]
    corrupted = gross_corruption(
        W2d, np.ones(W2d.shape, dtype=bool), shares, int(seed), low=sd["low"], high=sd["high"]
    )
    reg = dict(settings["regularizer"])  # the kernel method's options of reconstruct (depth_scale too)
    width = WIDTHS[settings["width"]]
    rtnh = dict(settings["robust_tnh"])
    huber = dict(settings["huber"])
    rows, arrays = [], {}
    for share in shares:
        Wc, displaced = corrupted[share]
        term = OrthographicReprojection(Wc, mask, R)
        shapes = {}

        def record(
            method,
            X,
            start,
            converged,
            n_iter,
            delta=np.nan,
            tau=np.nan,
            share=share,
            displaced=displaced,
            shapes=shapes,
        ):
            seconds = time.perf_counter() - start
            err = e3d(X, X_gt, P)
            rows.append(
                {
                    "sequence": name,
                    "displaced": float(share),
                    "seed": int(seed),
                    "method": method,
                    "e3d": err,
                    "seconds": seconds,
                    "converged": bool(converged),
                    "n_iter": int(n_iter),
                    "delta": float(delta),
                    "tau": float(tau),
                    "n_displaced": int(displaced.sum()),
                }
            )
            shapes[method] = X
            say(
                f"{name} displaced={share:g} seed={seed} {method:15s} e3d={err:.4f} {seconds:6.1f}s "
                f"ok={converged}"
            )

        start = time.perf_counter()
        tnh = reconstruct(Wc, mask, cameras=R, prior="tnh", method="admm", **dict(settings["tnh"]))
        record("TNH", tnh.x, start, tnh.success, tnh.nit)

        start = time.perf_counter()
        tau_r = robust_tnh_tau(term.shape, rtnh.pop("tau_factor"))
        robust = reconstruct(Wc, mask, cameras=R, prior="tnh", loss="huber", tau=tau_r, **rtnh)
        rtnh["tau_factor"] = settings["robust_tnh"]["tau_factor"]
        record("TNH (robust)", robust.x, start, robust.success, robust.nit, tau=tau_r)

        start = time.perf_counter()
        ls_args = dict(width=settings["width"], tau=settings["tau"], start=tnh)
        ls = reconstruct(Wc, mask, cameras=R, prior="kernel", **ls_args, **reg)
        record("Kernel (LS)", ls.x, start, ls.success, ls.nit, tau=settings["tau"])

        start = time.perf_counter()
        gamma = width(robust.x)
        delta, tau_k = huber_kernel_parameters(
            term, robust.x, tau_r, gamma, huber["delta_factor"], huber["balance"]
        )
        hub_reg = {**reg, **dict(huber.get("regularizer", {}))}
        huber_args = dict(loss="huber", delta=delta, width=gamma, tau=tau_k, start=robust)
        hub = reconstruct(Wc, mask, cameras=R, prior="kernel", **huber_args, **hub_reg)
        record("Kernel (Huber)", hub.x, start, hub.success, hub.nit, delta=delta, tau=tau_k)
        arrays[share] = Reconstructions(
            shapes=shapes, mask=mask, ground_truth=np.asarray(X_gt), extra={"displaced": displaced}
        )
    return pd.DataFrame(rows), arrays


class RobustNRSfM(MocapExperiment):
    """NRSfM with known cameras and displaced tracks: TNH and the kernel method, least squares against
    robust data terms (not in the paper)."""

    name = "robust_nrsfm"
    title = "Robust NRSfM: displaced 2D tracks, least squares against l1 / Huber data terms"
    in_paper = False
    notebook = "robust_nrsfm"
    render = {"digits": 4, "metrics": ["e3d"], "transpose": False}
    enumerates = ("sequences", "displaced", "n_seeds", "seed")

    def jobs(self, config):
        s = self.settings(config)
        return [
            Job(
                f"{seq}_seed{s['seed'] + k}",
                {"sequence": seq, "seed": s["seed"] + k, "displaced": [float(c) for c in s["displaced"]]},
            )
            for seq in s["sequences"]
            for k in range(s["n_seeds"])
        ]

    def check(self, config):
        s = self.settings(config)
        if s["displacement_sd"]["low"] > s["displacement_sd"]["high"]:
            raise ValueError(
                f"robust_nrsfm.displacement_sd: low must not exceed high; got {s['displacement_sd']}"
            )
        if s["width"] not in WIDTHS:
            raise ValueError(f"robust_nrsfm.width must be one of {tuple(WIDTHS)}; got {s['width']!r}")
        for c in s["displaced"]:
            if float(f"{c:g}") != c:
                raise ValueError(
                    f"robust_nrsfm.displaced: {c!r} prints as {c:g}; use at most 6 significant digits"
                )
        return super().check(config)

    def resources(self, config, job):
        return {"mem_mb": 1500, "runtime": 30}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        seq = self.load(job, settings, data_dir, progress)
        rows, recons = run_displaced(
            stack_to_rows(seq.W, dim=2),
            seq.R,
            stack_to_rows(seq.S, dim=3),
            shares=[float(c) for c in job.params["displaced"]],
            seed=int(job.params["seed"]),
            settings=settings,
            name=seq.name,
            progress=progress,
        )
        arrays = {}
        for share, recon in recons.items():
            arrays.update({f"displaced{share:g}_{k}": v for k, v in recon.to_arrays().items()})
        return JobOutput(rows=rows, arrays=arrays)

    def summarise(self, runs):
        required = {"sequence", "displaced", "seed", "method", "e3d"}
        missing = required - set(runs.columns)
        if missing:
            raise ValueError(f"runs lacks columns {sorted(missing)}; pass the rows of robust_nrsfm jobs")
        methods = [m for m in METHODS if m in set(runs["method"])]
        methods += sorted(set(runs["method"]) - set(METHODS))
        names = set(runs["sequence"])
        sequences = [s for s in SEQUENCES if s in names] + sorted(names - set(SEQUENCES))
        rows = []
        for seq in sequences:
            for c in sorted(runs["displaced"].unique()):
                for method in methods:
                    group = runs[
                        (runs["sequence"] == seq) & (runs["displaced"] == c) & (runs["method"] == method)
                    ]
                    if group.empty:
                        continue
                    per_seed = group.groupby("seed")["e3d"].mean()
                    stats = {**summary_stats(per_seed, "e3d", extremes=True), "n_seeds": float(len(per_seed))}
                    rows += [(f"{seq.capitalize()} displaced={c:g}", method, k, v) for k, v in stats.items()]
        for c in sorted(runs["displaced"].unique()):
            for method in methods:
                group = runs[(runs["displaced"] == c) & (runs["method"] == method)]
                if group.empty:
                    continue
                # (seed x sequence) errors: the Mean averages each sequence over its seeds; its spread
                # treats the across-sequence mean of one seed as one replicate
                grid = group.pivot_table(index="seed", columns="sequence", values="e3d", aggfunc="mean")
                stats = summary_stats(grid.dropna(axis=0, how="any").mean(axis=1), "e3d", extremes=True)
                stats["e3d"] = float(grid.mean(axis=0).mean())
                stats["n_seeds"] = float(grid.dropna(axis=0, how="any").shape[0])
                stats["n_sequences"] = float(grid.shape[1])
                rows += [(f"Mean displaced={c:g}", method, k, v) for k, v in stats.items()]
        return pd.DataFrame(rows, columns=["setting", "method", "metric", "value"])

    def caption(self, config):
        s = self.settings(config)
        shares = ", ".join(f"{c:.0%}" for c in s["displaced"])
        sd = s["displacement_sd"]
        return (
            f"Robust NRSfM (not in the paper): CMU mocap with ground-truth cameras "
            f"({every_nth_frame(s['step'])}), {shares} of the image coordinates displaced by "
            f"± {sd['low']:g}–{sd['high']:g} standard deviations of their track; e3D, mean ± sd over "
            f"{s['n_seeds']} seeds. TNH: exact fit. TNH (robust): l1 reprojection error, tau = "
            f"{s['robust_tnh']['tau_factor']:g} √max(F, 3P). Kernel (LS): Table 3's kernel method "
            f"(tau = {s['tau']:g}, {s['width']}) from TNH. Kernel (Huber): from TNH (robust), delta = "
            f"{s['huber']['delta_factor']:g} × MAD scale of its non-zero residuals, the kernel's tau from "
            "the robust start's balance of data and regularizer; no ground truth in any choice."
        )
