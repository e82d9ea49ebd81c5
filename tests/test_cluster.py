"""Runs outside the default route: cluster profiles and environments where nldr is not installed."""

import re
import subprocess
import sys

import pytest
import yaml
from protocol import QUICK, REPO, SNAKEMAKE

SCRIPTS = REPO / "workflow" / "scripts"


@pytest.mark.pipeline
@pytest.mark.parametrize("profile", ["slurm", "slurm-noacct"])
def test_slurm_profile_requests_each_jobs_threads(tmp_path, profile):
    """The full-length drink job runs BLAS on 2 threads; SLURM must be asked for 2 CPUs for it (a
    profile-wide cpus_per_task used to override threads), and 1 for the others. The real submission
    runs in tests/cluster/run_slurm_test.sh (`make cluster-test`)."""
    overlay = tmp_path / "drink.yaml"
    overlay.write_text("table3:\n  sequences: [drink, yoga]\ntable3_full:\n  n_seeds: 1\n")
    proc = subprocess.run(
        [*SNAKEMAKE, "-d", str(tmp_path), "--profile", str(REPO / "profiles" / profile), "-n",
         "results/quick/tables/table3_full.csv", "--configfile", str(QUICK), str(overlay)],
        cwd=REPO, capture_output=True, text=True,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    blocks = [b for b in re.split(r"\n(?=rule |localrule )", proc.stdout) if b.startswith("rule run_job")]
    requested = {}
    for block in blocks:
        job = re.search(r"runs/(\w+/\w+)\.csv", block).group(1)
        threads = re.search(r"threads: (\d+)", block)
        cpus = re.search(r"cpus_per_task=(\d+)", block)
        assert cpus, block
        requested[job] = (int(threads.group(1)) if threads else 1, int(cpus.group(1)))
    assert requested and all(t == c for t, c in requested.values()), requested
    assert requested["table3_full/drink_full_seed2016"] == (2, 2)


def test_the_no_accounting_profile_is_the_slurm_profile_plus_its_three_settings():
    """profiles/slurm-noacct must not drift from profiles/slurm: the same keys and values, plus the
    squeue status check, a short first check that squeue can still see through SLURM's default
    MinJobAge (300 s; the plugin falls back to sacct below 3 x that delay), and no account."""
    slurm = yaml.safe_load((REPO / "profiles/slurm/config.yaml").read_text())
    noacct = yaml.safe_load((REPO / "profiles/slurm-noacct/config.yaml").read_text())
    extra = {k: noacct.pop(k) for k in list(noacct) if k not in slurm}
    assert noacct == slurm
    assert extra.pop("slurm-status-command") == "squeue"
    assert 3 * extra.pop("slurm-init-seconds-before-status-checks") < 300
    assert not extra, extra
    assert "slurm_account" not in noacct["default-resources"]


def test_job_scripts_import_the_checkouts_src_when_nldr_is_not_installed():
    """As under `snakemake --use-conda`: the environment has the dependencies but not nldr."""
    code = f"""
import sys
sys.path = [p for p in sys.path if not p.rstrip('/').endswith('src')]
sys.meta_path = [f for f in sys.meta_path if 'editable' not in repr(f).lower()]
try:
    import nldr
except ImportError:
    pass
else:
    raise SystemExit('nldr is still importable: the test would not test the fallback')
sys.path.insert(0, {str(SCRIPTS)!r})
import _pipeline
import nldr.experiments
print(nldr.__file__)
"""
    env = {"PATH": "/usr/bin:/bin"}  # no PYTHONPATH
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == str(REPO / "src" / "nldr" / "__init__.py")
