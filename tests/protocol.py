"""The pipeline's protocols as the tests see them: config/config.yaml, and config/quick.yaml laid over
it (Snakemake merges nested blocks; quick.yaml lists only the keys that differ)."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import yaml
from snakemake.utils import update_config

REPO = Path(__file__).resolve().parents[1]
FULL = REPO / "config/config.yaml"
QUICK = REPO / "config/quick.yaml"
SNAKEMAKE = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile")]


def merged(base: dict, overlay: dict) -> dict:
    """``overlay`` laid over ``base`` by Snakemake's own merge (nested dicts merge, others replace)."""
    out = copy.deepcopy(base)
    update_config(out, copy.deepcopy(overlay))
    return out


def full_config() -> dict:
    return yaml.safe_load(FULL.read_text())


def quick_config() -> dict:
    """The quick protocol's complete config (every key, as the pipeline sees it)."""
    return merged(full_config(), yaml.safe_load(QUICK.read_text()))


def quick_results() -> str:
    """Folder of the quick protocol's outputs, relative to the working directory."""
    return quick_config()["results"]


def run_snakemake(workdir, *args, env=None):
    """Snakemake on this repository's Snakefile in ``workdir`` (``--configfile`` must come last)."""
    cmd = [*SNAKEMAKE, "-d", str(workdir), *args]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, env=env)
