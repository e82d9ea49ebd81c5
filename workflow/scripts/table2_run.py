"""One (p, mask) of Table 2: every completion method on the same seeded mask of oil flow."""

from _pipeline import setup, write_csv

from nldr.datasets import load_oil
from nldr.experiments.table2 import run_mask

sm = snakemake  # noqa: F821
log = setup(sm)
X, _ = load_oil("train", sm.params.data_dir)
X = X[: sm.params.n_rows]
params = {name: dict(kwargs) for name, kwargs in sm.params.methods.items()}
params.setdefault("Ours", {})["gamma"] = sm.params.gamma
for name in ("PKPCA", "RKPCA"):
    params.setdefault(name, {}).setdefault("gamma", sm.params.gamma)
runs = run_mask(X, p=float(sm.wildcards.p), seed=int(sm.wildcards.seed), params=params, progress=log.info)
write_csv(sm.output[0], runs)
