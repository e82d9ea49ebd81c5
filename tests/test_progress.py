"""Progress lines of the long searches outside the regularizer (verbose=True)."""

import numpy as np

from nldr.experiments._table4 import tune_tau


def test_tune_tau_verbose_prints_every_evaluation_and_changes_nothing(capsys):
    def objective(tau):
        return (np.log10(tau) - 0.3) ** 2 + 1.0

    quiet = tune_tau(objective, log10_bounds=(-1, 2), xatol=1e-2)
    assert capsys.readouterr().out == ""
    loud = tune_tau(objective, log10_bounds=(-1, 2), xatol=1e-2, verbose=True)
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == loud.nfev == quiet.nfev and loud.history == quiet.history
    for k, (line, (tau, value)) in enumerate(zip(lines, loud.history, strict=True), start=1):
        assert line.startswith(f"[tune_tau] evaluation {k}: tau={tau:.5g} objective={value:.5g} (")
