"""One (noise level, draw) of Table 1: KPCA ranks and the closed-form tau sweep on noisy oil flow."""

from _pipeline import setup, write_csv

from nldr.datasets import load_oil
from nldr.experiments.table1 import run_noise_level

sm = snakemake  # noqa: F821
log = setup(sm)
X_train, y_train = load_oil("train", sm.params.data_dir)
X_test, y_test = load_oil("test", sm.params.data_dir)
std, seed = float(sm.wildcards.std), int(sm.wildcards.seed)
log.info("noise std %g, seed %d, %d taus", std, seed, len(sm.params.taus))
runs = run_noise_level(
    X_train,
    y_train,
    X_test,
    y_test,
    noise_std=std,
    seed=seed,
    gamma=sm.params.gamma,
    max_rank=sm.params.max_rank,
    taus=sm.params.taus,
    center=sm.params.center,
)
best = runs[runs["best"]]
log.info("best:\n%s", best.to_string())
write_csv(sm.output[0], runs)
