"""The environment files agree: environment.yml installs this project with the pins of pyproject."""

import re
import tomllib

import yaml
from conftest import REPO


def test_environment_yml_matches_pyproject():
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    env = yaml.safe_load((REPO / "environment.yml").read_text())
    deps = env["dependencies"]
    python = next(d for d in deps if isinstance(d, str) and d.startswith("python"))
    assert python == "python=3.11"
    assert pyproject["project"]["requires-python"] == ">=3.11"
    pip = next(d["pip"] for d in deps if isinstance(d, dict))
    assert pip == ["-e .[dev]"]
    # every requirement is pinned exactly, so both routes install the same versions
    reqs = pyproject["project"]["dependencies"] + pyproject["project"]["optional-dependencies"]["dev"]
    for req in reqs:
        assert re.fullmatch(r"[A-Za-z0-9_.\-\[\]]+==[0-9][0-9A-Za-z.]*", req), req
    names = {re.split(r"[\[=]", r)[0].lower() for r in reqs}
    assert {
        "numpy",
        "scipy",
        "scikit-learn",
        "cvxpy",
        "pandas",
        "matplotlib",
        "snakemake",
        "papermill",
        "jupytext",
        "pytest",
        "hypothesis",
        "ruff",
        "nbmake",
    } <= names


def test_pipeline_conda_env_has_the_same_pins():
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    env = yaml.safe_load((REPO / "workflow/envs/nldr.yaml").read_text())
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    assert pip == pyproject["project"]["dependencies"]
    assert "python=3.11" in env["dependencies"]
