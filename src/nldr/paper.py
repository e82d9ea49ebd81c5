"""The paper's published numbers, as data, for side-by-side tables (Garg, Eriksson, Reid 2016).

Each table is a list of (setting, method, metric, value) records in the project's tidy format.
"""

from __future__ import annotations

import pandas as pd

__all__ = ["TABLE1", "TABLE2", "TABLE3", "TABLE4", "paper_frame"]

# Table 1: manifold error (relative, centred kernels) and 1-NN test error (percent) on oil flow.
TABLE1 = [
    (f"std={std}", method, metric, value)
    for std, kpca_err, cfs_err, kpca_cls, cfs_cls in [
        (0.2, 0.1099, 0.1068, 9.60, 9.60),
        (0.3, 0.2298, 0.2184, 19.90, 15.70),
        (0.4, 0.3522, 0.3339, 40.10, 22.20),
    ]
    for method, metric, value in [
        ("KPCA", "manifold_error", kpca_err),
        ("CFS", "manifold_error", cfs_err),
        ("KPCA", "classification_error_pct", kpca_cls),
        ("CFS", "classification_error_pct", cfs_cls),
    ]
]

# Table 2: oil-flow completion, sum of squared errors over 100 x 12, mean and std over 50 masks.
# None where the paper prints NA (1-NN at p = 0.5: no fully observed row remains).
_T2 = {
    "mean": [(13, 4), (28, 4), (70, 9), (139, 7)],
    "1-NN": [(5, 3), (14, 5), (90, 20), (None, None)],
    "PPCA": [(3.7, 0.6), (9, 2), (50, 10), (140, 30)],
    "PKPCA": [(5, 1), (12, 3), (32, 6), (100, 20)],
    "RKPCA": [(3.2, 1.9), (8, 4), (27, 8), (83, 15)],
    "Ours": [(2.3, 2), (6, 3), (22, 7), (70, 11)],
}
TABLE2 = [
    (f"p={p}", method, metric, value)
    for method, cells in _T2.items()
    for p, (mean, sd) in zip((0.05, 0.10, 0.25, 0.50), cells, strict=True)
    for metric, value in (("sse", mean), ("sse_sd", sd))
]

# Table 3: e3D with ground-truth cameras; Table 4: e3D with estimated cameras.
_SEQS = ("Drink", "Pickup", "Yoga", "Stretch", "Mean")
_T3 = [
    (0.0227, 0.0114, 0.0083, 0.0313, 0.0248, 0.0229),
    (0.0487, 0.0312, 0.0279, 0.0936, 0.0709, 0.0658),
    (0.0344, 0.0257, 0.0276, 0.0828, 0.0611, 0.0612),
    (0.0418, 0.0286, 0.0271, 0.0911, 0.0694, 0.0705),
    (0.0369, 0.0242, 0.0227, 0.0747, 0.0565, 0.0551),
]
_T4 = [
    (0.0947, 0.0926, 0.0906, 0.0957, 0.0942, 0.0937),
    (0.1282, 0.1071, 0.1059, 0.1598, 0.1354, 0.1339),
    (0.2912, 0.2683, 0.2639, 0.2821, 0.2455, 0.2457),
    (0.1094, 0.1043, 0.1031, 0.1398, 0.1459, 0.1484),
    (0.1559, 0.1430, 0.1409, 0.1694, 0.1552, 0.1554),
]


def _nrsfm(rows):
    out = []
    for seq, values in zip(_SEQS, rows, strict=True):
        for (missing, method), value in zip(
            [(m, k) for m in ("full", "missing50") for k in ("TNH", "Kernel d_max", "Kernel d_med")],
            values,
            strict=True,
        ):
            out.append((f"{seq} {missing}", method, "e3d", value))
    return out


TABLE3 = _nrsfm(_T3)
TABLE4 = _nrsfm(_T4)


def paper_frame(records) -> pd.DataFrame:
    """Records -> DataFrame with columns setting, method, metric, paper."""
    return pd.DataFrame(records, columns=["setting", "method", "metric", "paper"])
