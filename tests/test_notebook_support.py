"""nldr.experiments.notebook: the notebooks find the repository and the config from anywhere."""

from pathlib import Path

import pytest
import yaml
from protocol import REPO, quick_config

from nldr.experiments.notebook import cached, load_config, merge_config, need, repo_root


def test_repo_root_walks_up_from_a_subfolder_and_falls_back_to_the_checkout(tmp_path):
    assert repo_root(REPO / "notebooks") == REPO
    assert repo_root(REPO / "workflow" / "rules") == REPO
    # outside any checkout: the checkout this package was imported from (src layout)
    assert repo_root(tmp_path) == REPO


def test_load_config_lays_the_overlay_over_the_base_as_snakemake_does():
    assert load_config(REPO) == yaml.safe_load((REPO / "config/config.yaml").read_text())
    assert load_config(REPO, "config/quick.yaml") == quick_config()  # Snakemake's own merge
    assert merge_config({"a": {"b": 1, "c": 2}, "d": [1]}, {"a": {"b": 3}, "d": [2]}) == {
        "a": {"b": 3, "c": 2},
        "d": [2],
    }
    with pytest.raises(ValueError, match="configfile"):
        load_config(REPO, "config/missing.yaml")


def test_need_names_the_target_that_builds_a_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="snakemake -c all table2 --configfile config/quick.yaml"):
        need(tmp_path / "table2.csv", "table2")
    (tmp_path / "t.csv").write_text("x\n")
    assert need(tmp_path / "t.csv", "table2") == tmp_path / "t.csv"


def test_cached_computes_once_per_key_and_recomputes_on_request(tmp_path):
    calls = []

    def compute():
        calls.append(1)
        return {"n": len(calls)}

    assert cached(tmp_path, "x", {"tau": 0.1}, compute) == {"n": 1}
    assert cached(tmp_path, "x", {"tau": 0.1}, compute) == {"n": 1}  # read back, not recomputed
    assert cached(tmp_path, "x", {"tau": 0.2}, compute) == {"n": 2}  # another key: computed
    assert cached(tmp_path, "x", {"tau": 0.1}, compute, recompute=True) == {"n": 3}
    assert cached(tmp_path, "x", {"tau": 0.1}, compute) == {"n": 3}  # the recomputed value was kept
    assert not [p for p in Path(tmp_path).iterdir() if p.name.startswith(".")]  # no temporaries left
