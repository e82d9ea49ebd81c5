"""The config schema is the contract: checked in-process (no Snakemake run), so every bad value can be
tried cheaply. The pipeline tests in test_reliability.py check that Snakemake applies it before any job."""

import copy

import pytest
from protocol import REPO, full_config, quick_config
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

SCHEMA = str(REPO / "workflow/schemas/config.schema.yaml")


def _with(config, path, value):
    config = copy.deepcopy(config)
    *parents, last = path
    node = config
    for key in parents:
        node = node[key]
    node[last] = value
    return config


@pytest.mark.parametrize("config", [full_config(), quick_config()], ids=["full", "quick"])
def test_both_protocols_are_valid(config):
    validate(copy.deepcopy(config), SCHEMA)


@pytest.mark.parametrize(
    "path, value",
    [
        (("table2", "methods", "Ours", "bogus_kw"), 1),  # unknown keyword under a method
        (("table2", "methods", "PPCA", "bogus_kw"), 1),
        (("table3", "regularizer", "bogus_kw"), 1),
        (("table4", "kernel", "bogus_kw"), 1),
        (("table1", "tau", "bogus_kw"), 1),
        (("selection", "schedule", "bogus_kw"), 1),
        (("selection", "grid", "bogus_kw"), 1),
        (("data", "bogus_kw"), 1),
    ],
)
def test_unknown_nested_keys_are_refused(path, value):
    with pytest.raises(WorkflowError, match=path[-1]):
        validate(_with(full_config(), path, value), SCHEMA)
