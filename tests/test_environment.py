"""Packaging: the library asks for ranges, constraints.txt pins every package exactly, and the other
install routes (environment.yml, the pipeline's conda env) agree with both."""

import re
import tomllib

import yaml
from conftest import REPO
from packaging.requirements import Requirement
from packaging.version import Version

import nldr

PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())


def constraints() -> dict[str, str]:
    pins = {}
    for line in (REPO / "constraints.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, version = line.split("==")
            pins[name.lower().replace("_", "-")] = version.strip()
    return pins


def test_core_dependencies_are_ranges_and_tools_are_extras():
    core = [Requirement(r) for r in PYPROJECT["project"]["dependencies"]]
    assert {r.name for r in core} == {"numpy", "scipy", "scikit-learn", "pandas", "threadpoolctl", "pooch"}
    assert all(not any(s.operator == "==" for s in r.specifier) for r in core)  # ranges, not pins
    extras = PYPROJECT["project"]["optional-dependencies"]
    assert {"plot", "cvxpy", "pipeline", "dev"} <= set(extras)
    pipeline = {Requirement(r).name for r in extras["pipeline"]}
    assert {"snakemake", "papermill", "jupytext", "jupyter"} <= pipeline


def test_one_version_string():
    assert PYPROJECT["project"]["dynamic"] == ["version"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "nldr.__version__"}
    assert "version" not in PYPROJECT["project"]
    assert re.fullmatch(r"\d+\.\d+\.\d+", nldr.__version__)


def test_constraints_pin_every_requirement_inside_its_range():
    pins = constraints()
    extras = PYPROJECT["project"]["optional-dependencies"]
    groups = [PYPROJECT["project"]["dependencies"], *extras.values()]
    reqs = [Requirement(r) for group in groups for r in group]
    for req in reqs:
        if req.name == "nldr":  # self-referencing extras
            continue
        assert req.name.lower() in pins, f"{req.name} is not pinned in constraints.txt"
        assert Version(pins[req.name.lower()]) in req.specifier, (req, pins[req.name.lower()])


def test_environment_yml_installs_with_the_constraints():
    env = yaml.safe_load((REPO / "environment.yml").read_text())
    deps = env["dependencies"]
    assert "python=3.11" in deps and PYPROJECT["project"]["requires-python"] == ">=3.11"
    pip = next(d["pip"] for d in deps if isinstance(d, dict))
    assert pip == ["-c constraints.txt", "-e .[dev]"]


def test_pipeline_conda_env_has_the_constraints_versions():
    env = yaml.safe_load((REPO / "workflow/envs/nldr.yaml").read_text())
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    pins = constraints()
    for line in pip:
        req = Requirement(line)
        (spec,) = req.specifier
        assert spec.operator == "==" and spec.version == pins[req.name.lower()], line
    names = {Requirement(line).name for line in pip}
    assert {Requirement(r).name for r in PYPROJECT["project"]["dependencies"]} <= names


def test_citation_file_names_this_version_and_the_paper():
    cff = yaml.safe_load((REPO / "CITATION.cff").read_text())
    assert cff["version"] == nldr.__version__
    assert "1603.05015" in cff["preferred-citation"]["url"]
    assert (REPO / "LICENSE").read_text().startswith("MIT License")
