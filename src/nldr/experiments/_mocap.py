"""What the NRSfM experiments (Tables 3 and 4, and Table 3 on every frame) share: their jobs (one per
CMU mocap sequence, setting and mask seed), the kernel-width criteria, the saved reconstructions, and
the e3D summary with the paper's Mean rows."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..datasets import load_mocap
from ..nrsfm._reconstruct import WIDTH_RULES
from .base import Experiment, Job, summary_stats

__all__ = [
    "WIDTHS",
    "METHODS",
    "SEQUENCES",
    "setting_label",
    "check_sequence",
    "Reconstructions",
    "summarise_e3d",
    "MocapExperiment",
]

#: Kernel-width criteria: name -> gamma of the RBF kernel from the TNH shapes (samples as rows); the
#: library's :data:`nldr.nrsfm._reconstruct.WIDTH_RULES`.
WIDTHS: dict[str, Callable[[np.ndarray], float]] = WIDTH_RULES
#: Method labels in the paper's column order.
METHODS = ("TNH", "Kernel d_max", "Kernel d_med")
#: The paper's sequences, in its row order.
SEQUENCES = ("drink", "pickup", "yoga", "stretch")


def setting_label(missing_fraction: float) -> str:
    """``"full"`` for 0, else ``"missing<percent>"`` (``0.5 -> "missing50"``), as in :mod:`nldr.paper`."""
    return "full" if missing_fraction == 0 else f"missing{round(100 * float(missing_fraction)):d}"


def check_sequence(seq, table: str = "this experiment") -> None:
    """ValueError unless ``seq`` is a :class:`~nldr.datasets.MocapSequence` with ground-truth cameras."""
    for attr in ("name", "W", "S", "R"):
        if not hasattr(seq, attr):
            raise ValueError(f"seq must be a MocapSequence (nldr.datasets.load_mocap); it has no {attr!r}")
    if seq.R is None:
        raise ValueError(f"sequence {seq.name!r} has no ground-truth cameras (R is None); {table} needs them")


@dataclass
class Reconstructions:
    """The arrays an NRSfM job saves, and the one place their layout in the ``.npz`` is defined.

    Attributes
    ----------
    shapes : dict
        Method -> reconstruction, array (F, 3P): shapes as rows, unit of the data, unaligned.
    mask : bool array, shape (F, P)
        True where the point was observed.
    ground_truth : array, shape (F, 3P)
    cameras : dict
        Method (and ``"rigid"`` for Table 4's initial cameras) -> cameras (F, 2, 3); empty with known cameras.
    extra : dict
        Further named arrays (e.g. Table 4's ``tau_search``, rows of (tau, e3d)).
    """

    shapes: dict[str, np.ndarray]
    mask: np.ndarray
    ground_truth: np.ndarray
    cameras: dict[str, np.ndarray] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Flat name -> array mapping for ``np.savez`` (method names are stored, arrays by index)."""
        methods = list(self.shapes)
        arrays = {"methods": np.array(methods), "mask": self.mask, "ground_truth": self.ground_truth}
        arrays.update({f"shape_{i}": self.shapes[m] for i, m in enumerate(methods)})
        if "rigid" in self.cameras:
            arrays["rigid_cameras"] = self.cameras["rigid"]
        arrays.update({f"cameras_{i}": self.cameras[m] for i, m in enumerate(methods) if m in self.cameras})
        arrays.update(self.extra)
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping) -> Reconstructions:
        """Inverse of :meth:`to_arrays` (accepts an open ``np.load`` result)."""
        methods = [str(m) for m in arrays["methods"]]
        keys = set(arrays.keys()) if hasattr(arrays, "keys") else set(arrays)
        cameras = {m: arrays[f"cameras_{i}"] for i, m in enumerate(methods) if f"cameras_{i}" in keys}
        if "rigid_cameras" in keys:
            cameras["rigid"] = arrays["rigid_cameras"]
        known = {"methods", "mask", "ground_truth", "rigid_cameras"}
        extra = {
            k: arrays[k] for k in keys if k not in known and not k.startswith(("shape_", "cameras_"))
        }
        return cls(
            shapes={m: arrays[f"shape_{i}"] for i, m in enumerate(methods)},
            mask=np.asarray(arrays["mask"], dtype=bool),
            ground_truth=arrays["ground_truth"],
            cameras=cameras,
            extra=extra,
        )


def _sequence_order(names) -> list[str]:
    known = [s for s in SEQUENCES if s in set(names)]
    return known + sorted(set(names) - set(SEQUENCES))


def _e3d_stats(per_seed: pd.Series) -> dict[str, float]:
    stats = summary_stats(per_seed, "e3d", extremes=True)
    stats["n_seeds"] = float(per_seed.notna().sum())
    return stats


def summarise_e3d(runs: pd.DataFrame) -> pd.DataFrame:
    """NRSfM job rows -> tidy ``setting, method, metric, value`` rows of a Table 3/4-style table.

    Settings are ``"<Sequence> <full|missing50>"`` as in :data:`nldr.paper.TABLE3`, plus
    ``"Mean <full|missing50>"``. Per sequence, setting and method: ``e3d`` is the mean over seeds,
    ``e3d_sd`` the sample standard deviation over seeds (NaN with one seed), ``e3d_min``,
    ``e3d_max`` and ``n_seeds``. The Mean rows follow the paper (the mean over sequences): ``e3d``
    is the mean over the sequences of their per-sequence means; the spread metrics treat the
    across-sequence mean of one seed as one replicate, over the seeds every sequence ran
    (``n_seeds`` counts them); ``n_sequences`` says how many sequences entered the mean.
    """
    required = {"sequence", "missing_fraction", "seed", "method", "e3d"}
    missing = required - set(runs.columns)
    if missing:
        raise ValueError(f"runs lacks columns {sorted(missing)}; pass the rows of an NRSfM job")
    methods = [m for m in METHODS if m in set(runs["method"])]
    methods += sorted(set(runs["method"]) - set(METHODS))
    sequences = _sequence_order(runs["sequence"].unique())
    rows = []
    for frac in sorted(runs["missing_fraction"].unique()):
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
                for metric, value in _e3d_stats(per_seed).items():
                    rows.append((f"{seq.capitalize()} {label}", method, metric, value))
        for method in methods:
            group = runs[(runs["missing_fraction"] == frac) & (runs["method"] == method)]
            if group.empty:
                continue
            # (seed x sequence) table of errors; the Mean's value averages each sequence over its seeds
            grid = group.pivot_table(index="seed", columns="sequence", values="e3d", aggfunc="mean")
            stats = _e3d_stats(grid.dropna(axis=0, how="any").mean(axis=1))
            stats["e3d"] = float(grid.mean(axis=0).mean())
            stats["n_sequences"] = float(grid.shape[1])
            for metric, value in stats.items():
                rows.append((f"Mean {label}", method, metric, value))
    return _paper_order(pd.DataFrame(rows, columns=["setting", "method", "metric", "value"]))


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


def every_nth_frame(step: int) -> str:
    """'every frame', 'every 2nd frame', ..., 'every 10th frame' (for captions)."""
    suffix = {1: "st", 2: "nd", 3: "rd"}.get(step % 10 if step % 100 not in (11, 12, 13) else 0, "th")
    return "every frame" if step == 1 else f"every {step}{suffix} frame"


class MocapExperiment(Experiment):
    """Jobs over CMU mocap sequences: per sequence one full-data job (seed ``seed``) and ``n_seeds``
    missing-data jobs (seeds ``seed + k``); tables of e3D with the paper's Mean rows."""

    render = {"metrics": ["e3d"]}
    enumerates = ("sequences", "n_seeds", "seed", "missing_fraction")

    def jobs(self, config):
        s = self.settings(config)
        jobs = [
            Job(f"{seq}_full_seed{s['seed']}", {"sequence": seq, "missing_fraction": 0.0, "seed": s["seed"]})
            for seq in s["sequences"]
        ]
        jobs += [
            Job(
                f"{seq}_missing_seed{s['seed'] + k}",
                {"sequence": seq, "missing_fraction": s["missing_fraction"], "seed": s["seed"] + k},
            )
            for seq in s["sequences"]
            for k in range(s["n_seeds"])
        ]
        return jobs

    def data_files(self, config, job=None):
        sequences = [job.params["sequence"]] if job else self.settings(config)["sequences"]
        return [f"nrsfm/{seq}.mat" for seq in sequences]

    def load(self, job, settings, data_dir, progress=None):
        """The job's sequence, subsampled to ``settings['step']``; one line to ``progress`` about it."""
        seq = load_mocap(job.params["sequence"], data_dir).subsample(settings["step"])
        if progress is not None:
            progress(f"{seq.name}: {seq.n_frames} frames, {seq.n_points} points, job {job.id}")
        return seq

    def summarise(self, runs):
        return summarise_e3d(runs)
