"""Denoising (not in the paper): scikit-learn's digits with Gaussian noise, four denoisers.

Data: ``sklearn.datasets.load_digits`` (1797 images of 8 x 8 pixels, shipped inside scikit-learn, no
download), scaled to [0, 1]. One job = one noise level sigma and one seed: a seeded permutation gives a
training split and a test split, both with i.i.d. N(0, sigma^2) noise added (not clipped). Methods:

- ``PCA``: fitted on the noisy training split, test images projected and reconstructed;
- ``KernelPCA``: scikit-learn's ``KernelPCA(kernel="rbf", fit_inverse_transform=True)`` fitted on the
  noisy training split, as in scikit-learn's own denoising example;
- ``RobustKernelPCA``: fitted on the noisy training split; each test image denoised with every pixel
  observed and a finite rho (:class:`nldr.impute.RobustKernelPCAImputer`, the pre-image step of
  :meth:`~nldr.robust_kpca.RobustKernelPCA.complete`);
- ``Ours``: the regularizer (:func:`nldr.regularizer.minimize_regularized`), transductive on the noisy
  test images alone (the first ``ours.n_images``; its cost grows as n^2 per evaluation).

Every knob is chosen by hold-out CV on noisy data only (:class:`nldr.model_selection.HoldoutSearch`),
by held-out pixels (the J-invariance argument of Batson and Royer, "Noise2Self", 2019): the pixels
are split at random into ``cv.n_parts`` groups J;
a denoiser predicts the pixels of J from the other pixels only, and is scored by the squared
difference to the noisy values of J. As the noise on J is independent of that prediction, the expected
score is the prediction's squared error against the clean pixels plus sigma^2 per pixel, a constant, so
the knob with the lowest score is, in expectation, the one with the lowest clean error of the held-out
prediction. Hiding J is native for the regularizer (mask False on J); for the fit-then-apply methods
J is filled with the training split's pixel means before their reconstruction. ``RobustKernelPCA`` is
scored the same way (J filled, then denoised with every pixel observed), not by completing J: its knob
rho sets how far observed pixels move, and a prediction of hidden pixels alone would not penalise a rho
too small to denoise. Scoring a reconstruction against the noisy image it was computed from would instead
reward the identity (no denoising). Fit-then-apply methods are fitted on the first part of the noisy
training split and scored on the rest (``cv.validation``); ``Ours`` is scored on the noisy test images
themselves, which is legitimate (only their noisy values are used).

Metric ``mse``: mean squared error per pixel against the clean test images, over all test images
(``mse_subset``: the images ``Ours`` solves).
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
from sklearn.datasets import load_digits
from sklearn.decomposition import PCA, KernelPCA
from sklearn.impute import SimpleImputer
from sklearn.pipeline import Pipeline

from ..impute import DecompositionDenoiser, KernelRegularizerImputer, RobustKernelPCAImputer
from ..model_selection import HoldoutSearch
from .base import Experiment, Job, JobOutput, summary_stats

__all__ = ["Denoising", "METHODS", "noisy_digits", "pixel_parts"]

METHODS = ("Ours", "RobustKernelPCA", "KernelPCA", "PCA")


def noisy_digits(noise: float, seed: int, n_train: int, n_test: int):
    """Clean and noisy (train, test) splits of the digits in [0, 1]: four (n, 64) arrays."""
    X = load_digits().data / 16.0
    rng = np.random.default_rng(seed)
    idx = rng.permutation(X.shape[0])[: n_train + n_test]
    clean = X[idx]
    noisy = clean + noise * rng.standard_normal(clean.shape)
    return clean[:n_train], noisy[:n_train], clean[n_train:], noisy[n_train:]


def pixel_parts(shape: tuple[int, int], n_parts: int, seed: int) -> list[np.ndarray]:
    """Each image's pixels split at random into n_parts groups: n_parts (m, d) boolean masks (True =
    held out) that partition every row; a seeded, independent permutation per image, so no pixel is
    held out in every image at once."""
    rng = np.random.default_rng(seed)
    labels = np.argsort(rng.random(shape), axis=1) % n_parts
    return [labels == k for k in range(n_parts)]


def _sum_squared(Y, Y_hat, J) -> float:
    """||Y_hat[J] - Y[J]||^2, the held-out-pixel score (summed over a part's pixels)."""
    return float(np.sum((Y_hat - Y)[J] ** 2))


def _grids(cv):
    """Each method's candidates, in the order of the search (a tie goes to the first)."""
    return {
        "PCA": [{"n_components": k} for k in cv["pca_components"]],
        "KernelPCA": [
            {"gamma": g, "n_components": k, "alpha": a}
            for g, k, a in itertools.product(cv["gammas"], cv["kpca_components"], cv["kpca_alpha"])
        ],
        "RobustKernelPCA": [
            {"gamma": g, "tau": t, "rho": r}
            for g, t, r in itertools.product(cv["gammas"], cv["rkpca_tau"], cv["rkpca_rho"])
        ],
    }


def _denoiser(method: str) -> tuple[Pipeline, str]:
    """A fit-then-apply method as an estimator of images with NaN at held-out pixels, and the prefix
    of its knobs: held-out pixels filled with the fit's pixel means (SimpleImputer), then the
    reconstruction (PCA, KernelPCA) or RobustKernelPCA's denoising with every pixel observed."""
    if method == "RobustKernelPCA":
        denoise = RobustKernelPCAImputer(standardize=False)  # its grid's widths are in the pixels' units
        return Pipeline([("fill", SimpleImputer()), ("denoise", denoise)]), "denoise__"
    model = PCA() if method == "PCA" else KernelPCA(kernel="rbf", fit_inverse_transform=True)
    denoiser = DecompositionDenoiser(model)
    return Pipeline([("fill", SimpleImputer()), ("denoise", denoiser)]), "denoise__estimator__"


def _validation_folds(n_fit: int, parts: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
    """The search's folds on the training split: fit on its first ``n_fit`` images, score each pixel
    part J (boolean (n_val, d)) of the others, held out."""
    folds = []
    for J in parts:
        fit_rows = np.arange(n_fit + J.shape[0]) < n_fit
        folds.append((fit_rows, np.vstack([np.zeros((n_fit, J.shape[1]), dtype=bool), J])))
    return folds


class Denoising(Experiment):
    """Digits with Gaussian noise: the regularizer and RobustKernelPCA against KernelPCA and PCA."""

    name = "denoising"
    title = "Denoising scikit-learn's digits: the regularizer and RobustKernelPCA against KernelPCA and PCA"
    in_paper = False
    notebook = "denoising"
    figures = ("denoising_digits",)
    render = {"digits": 4, "metrics": ["mse", "mse_subset"], "transpose": True}
    enumerates = ("noise", "n_seeds", "seed")
    figure_captions = {
        "denoising_digits": "Digits denoised (first seed's test images at the figure's noise level): clean, "
        "noisy, and each method's output; knobs by held-out-pixel CV on noisy data."
    }

    def jobs(self, config):
        s = self.settings(config)
        return [
            Job(f"noise{v:g}_seed{s['seed'] + k}", {"noise": v, "seed": s["seed"] + k})
            for v in s["noise"]
            for k in range(s["n_seeds"])
        ]

    def resources(self, config, job):
        return {"mem_mb": 1000, "runtime": 10}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        say = progress or (lambda line: None)
        noise, seed = job.params["noise"], job.params["seed"]
        _, Y_train, clean, Y_test = noisy_digits(noise, seed, settings["n_train"], settings["n_test"])
        cv, ours = settings["cv"], settings["ours"]
        n_val = int(round(cv["validation"] * Y_train.shape[0]))
        n_sub = ours["n_images"]
        parts = pixel_parts((n_val, Y_train.shape[1]), cv["n_parts"], seed)
        parts_sub = pixel_parts((n_sub, Y_train.shape[1]), cv["n_parts"], seed + 1)
        rows, arrays = [], {"clean": clean[:16], "noisy": Y_test[:16]}
        grids = _grids(cv)

        def record(method, X_hat, params):
            err = (X_hat - clean[: X_hat.shape[0]]) ** 2
            rows.append(
                {
                    "noise": noise,
                    "seed": seed,
                    "method": method,
                    "mse": float(err.mean()) if X_hat.shape[0] == clean.shape[0] else np.nan,
                    "mse_subset": float(err[:n_sub].mean()),
                    "params": repr(params),
                }
            )
            arrays[method] = X_hat[:16]
            say(f"noise={noise} seed={seed} {method:16s} mse={rows[-1]['mse']:.5f} {params}")

        folds = _validation_folds(Y_train.shape[0] - n_val, parts)
        for method in ("PCA", "KernelPCA", "RobustKernelPCA"):
            estimator, prefix = _denoiser(method)
            grid = [{prefix + key: [value] for key, value in c.items()} for c in grids[method]]
            search = HoldoutSearch(estimator, grid, folds=folds, scoring=_sum_squared).fit(Y_train)
            record(method, search.transform(Y_test), grids[method][search.best_index_])

        if n_sub > 0:
            # Ours: transductive on the noisy test images; the pixel parts are the search's folds
            schedule = dict(ours["schedule"])
            ours = KernelRegularizerImputer(standardize=False, method="exact", **schedule, denoise=True)
            grid = {"gamma": list(cv["ours_gammas"]), "tau": list(cv["ours_tau"])}
            search = HoldoutSearch(ours, grid, folds=parts_sub, scoring=_sum_squared)
            record("Ours", search.fit_transform(Y_test[:n_sub]), search.best_params_)
        return JobOutput(rows=pd.DataFrame(rows), arrays=arrays)

    def summarise(self, runs):
        out = []
        for noise in sorted(runs["noise"].unique()):
            for method in [m for m in METHODS if m in set(runs["method"])]:
                group = runs[(runs["noise"] == noise) & (runs["method"] == method)]
                stats = {"n_seeds": float(len(group))}
                for metric in ("mse", "mse_subset"):
                    stats.update(summary_stats(group[metric], metric))
                for metric, value in stats.items():
                    out.append((f"noise={noise:g}", method, metric, float(value)))
        return pd.DataFrame(out, columns=["setting", "method", "metric", "value"])

    def caption(self, config):
        s = self.settings(config)
        return (
            "Denoising (not in the paper): scikit-learn's digits in [0, 1] with Gaussian noise of sd "
            f"'noise'; PCA, KernelPCA and RobustKernelPCA fitted on {s['n_train']} noisy training images "
            f"and applied to {s['n_test']} noisy test images; Ours transductive on the first "
            f"{s['ours']['n_images']} noisy test images alone (compare on mse_subset). Mean squared error "
            f"per pixel against the clean images, mean ± sd over {s['n_seeds']} seeds; every knob by "
            f"held-out-pixel CV ({s['cv']['n_parts']} pixel groups) on noisy data only."
        )

    def draw(self, figure, runs, arrays, data_dir):
        if figure != "denoising_digits":
            return super().draw(figure, runs, arrays, data_dir)
        import matplotlib.pyplot as plt

        job = sorted(arrays)[0]
        for candidate in sorted(arrays):  # the middle noise level's first seed if there are several
            if candidate.startswith("noise0.2_"):
                job = candidate
                break
        a = arrays[job]
        panels = ["clean", "noisy"] + [m for m in METHODS if m in a]
        n = min(8, a["clean"].shape[0])
        fig, axes = plt.subplots(len(panels), n, figsize=(n * 0.9, len(panels) * 1.0), squeeze=False)
        for i, name in enumerate(panels):
            for j in range(n):
                ax = axes[i, j]
                ax.imshow(np.clip(a[name][j], 0, 1).reshape(8, 8), cmap="gray_r", vmin=0, vmax=1)
                ax.set_xticks([])
                ax.set_yticks([])
            label = name
            if name != "clean":  # error of the images shown, against the clean ones
                mse = float(np.mean((a[name][:n] - a["clean"][:n]) ** 2))
                label = f"{name}\nMSE {mse:.4f}"
            axes[i, 0].set_ylabel(label, rotation=0, ha="right", va="center", fontsize=8)
        noise, seed = job.split("_")[0].removeprefix("noise"), job.split("_")[-1].removeprefix("seed")
        fig.suptitle(f"noise sd {noise}, seed {seed}: the first {n} test images", fontsize=9)
        fig.tight_layout()
        return fig
