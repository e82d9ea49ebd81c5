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


@pytest.mark.parametrize(
    "path, value, named",
    [
        (("table2", "n_masks"), 10**9, "n_masks"),  # would build a 10^9-item job list
        (("table1", "n_draws"), 10**6, "n_draws"),
        (("table1", "tau", "num"), 10**8, "num"),
        (("table3", "n_seeds"), 10**6, "n_seeds"),
        (("table2_full", "n_rows"), 5000, "n_rows"),  # DataTrn.txt has 1000 rows
        (("table3", "step"), 100000, "step"),
        (("table2", "methods", "PKPCA"), {"bogus_kw": 1}, "bogus_kw"),
        (("table2", "methods", "RKPCA"), {"gamma": -5}, "gamma"),  # gamma is table2.gamma, not a kwarg
        (("table2", "methods", "RKPCA"), {"n_components": 0}, "n_components"),
        (("table2", "p"), [0.1, 0.1], "p"),
        (("data", "dir"), "../../x", "dir"),
        (("data", "dir"), "resources/../../x", "dir"),
    ],
)
def test_out_of_bounds_values_are_refused_naming_the_key(path, value, named):
    with pytest.raises(WorkflowError, match=named):
        validate(_with(full_config(), path, value), SCHEMA)


@pytest.mark.parametrize("folder", ["resources", "data/raw", "/srv/mirror/nldr", "..hidden"])
def test_data_folders_inside_the_project_or_absolute_are_accepted(folder):
    validate(_with(full_config(), ("data", "dir"), folder), SCHEMA)


@pytest.mark.parametrize(
    "experiment, path, value, message",
    [
        ("table2", ("table2", "p"), [0.2, 0.2000001], r"table2\.p: 0\.2000001 prints as 0\.2"),
        ("table1", ("table1", "noise_std"), [0.30000001], r"table1\.noise_std: .* prints as 0\.3"),
        ("table1", ("table1", "tau", "min"), 1e4, r"table1\.tau: min must be below max"),
        ("table4", ("table4", "tnh", "log10_tau_bounds"), [2.0, -1.0], r"table4\.tnh\.log10_tau_bounds"),
        ("selection", ("selection", "grid", "log10_tau", "min"), 3.0, r"selection\.grid\.log10_tau"),
    ],
)
def test_cross_field_checks_name_the_key(experiment, path, value, message):
    from nldr.experiments import get

    config = _with(full_config(), path, value)
    validate(copy.deepcopy(config), SCHEMA)  # the schema alone cannot see these
    with pytest.raises(ValueError, match=message):
        get(experiment).check(config)


def test_every_experiment_passes_its_checks_on_both_protocols():
    from nldr.experiments import EXPERIMENTS

    for config in (full_config(), quick_config()):
        for experiment in EXPERIMENTS.values():
            assert [j.id for j in experiment.check(config)] == [j.id for j in experiment.jobs(config)]
