"""The structure stays as docs/ARCHITECTURE.md describes it: no import cycle in src/nldr, no private
name imported across modules, modules of a readable size, every experiment complete, and the quick
protocol planning nothing under the full protocol's result paths."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import REPO

from nldr.experiments import EXPERIMENTS

SRC = REPO / "src"
MAX_MODULE_LINES = 550  # "no module over about 500 lines"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(p): p for p in sorted((SRC / "nldr").rglob("*.py"))}


def resolve(module: str, node: ast.ImportFrom) -> str:
    """Absolute module named by a (possibly relative) ``from X import ...``."""
    if node.level == 0:
        return node.module or ""
    is_package = MODULES[module].name == "__init__.py"
    base = module.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports(module: str):
    """(target module, imported names, line) for every nldr import of ``module``, at any depth."""
    tree = ast.parse(MODULES[module].read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            target = resolve(module, node)
            if not target.startswith("nldr"):
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                yield (sub if sub in MODULES else target), alias.name, node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("nldr"):
                    yield alias.name, None, node.lineno


def test_no_import_cycle_in_the_library():
    graph = {m: {t for t, _, _ in imports(m) if t in MODULES and t != m} for m in MODULES}
    # a package's __init__ importing its own submodules is how packages work, not a cycle
    for m in MODULES:
        if MODULES[m].name == "__init__.py":
            graph[m] = {t for t in graph[m] if not t.startswith(m + ".")}
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for t in sorted(graph[m]):
            if state.get(t) == "open":
                cycle = stack[stack.index(t) :] + [t]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if t not in state:
                visit(t)
        stack.pop()
        state[m] = "done"

    for m in MODULES:
        if m not in state:
            visit(m)


def package_of(module: str) -> str:
    """The top-level unit a module belongs to: ``nldr.impute._linear`` -> ``nldr.impute``; a top-level
    module (``nldr.kernels``) is its own unit."""
    return ".".join(module.split(".")[:2])


def package_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """The first cycle of a directed graph (depth-first, sorted order), or None."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for target in sorted(graph.get(node, ())):
            if state.get(target) == "open":
                return stack[stack.index(target) :] + [target]
            if target not in state and (found := visit(target)):
                return found
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def package_graph() -> dict[str, set[str]]:
    """Edges between the library's packages and top-level modules, from imports at any depth (a
    function-local import is an edge too); a package's edges to its own modules are dropped."""
    graph: dict[str, set[str]] = {}
    for m in MODULES:
        for target, _, _ in imports(m):
            a, b = package_of(m), package_of(target)
            if a != b and b != "nldr":
                graph.setdefault(a, set()).add(b)
    return graph


def test_no_dependency_between_packages_in_both_directions():
    cycle = package_cycle(package_graph())
    assert cycle is None, "package cycle: " + " -> ".join(cycle)


def test_the_package_cycle_check_finds_a_planted_cycle():
    graph = {k: set(v) for k, v in package_graph().items()}
    graph.setdefault("nldr.model_selection", set()).add("nldr.impute")  # the edge a grid import would add
    assert package_cycle(graph) is not None
    assert package_cycle({"a": {"b"}, "b": {"c"}}) is None


def test_no_private_name_is_imported_across_modules():
    offences = [
        f"{MODULES[m].relative_to(REPO)}:{line} imports {name} from {target}"
        for m in MODULES
        for target, name, line in imports(m)
        if name and name.startswith("_") and not name.startswith("__") and target != m
    ]
    assert not offences, "\n".join(offences)


def test_modules_stay_readable():
    long = {m: n for m, p in MODULES.items() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, long


@pytest.mark.parametrize("name", list(EXPERIMENTS))
def test_every_experiment_has_its_config_block_schema_notebook_and_caption(name):
    experiment = EXPERIMENTS[name]
    config = yaml.safe_load((REPO / "config/config.yaml").read_text())
    schema = yaml.safe_load((REPO / "workflow/schemas/config.schema.yaml").read_text())
    assert name in config and name in schema["properties"] and name in schema["required"]
    jobs = experiment.jobs(config)
    assert jobs and len({j.id for j in jobs}) == len(jobs)  # ids name files: unique
    assert experiment.caption(config)
    if experiment.notebook:
        assert (REPO / "notebooks" / f"{experiment.notebook}.py").is_file()
    if experiment.in_paper:
        assert experiment.paper, "a paper table carries the paper's numbers"
    for figure in experiment.figures:
        assert experiment.figure_captions.get(figure)


def test_quick_config_lists_only_keys_that_differ():
    full = yaml.safe_load((REPO / "config/config.yaml").read_text())
    quick = yaml.safe_load((REPO / "config/quick.yaml").read_text())

    def same(a, b, path=""):
        for key, value in a.items():
            if isinstance(value, dict):
                same(value, b[key], f"{path}{key}.")
            else:
                assert value != b[key], f"quick.yaml repeats {path}{key} = {value!r}"

    same(quick, full)
    assert quick["results"] != full["results"]


@pytest.mark.pipeline
def test_quick_protocol_plans_nothing_under_the_full_protocols_results(tmp_path):
    full_results = yaml.safe_load((REPO / "config/config.yaml").read_text())["results"]
    quick_results = yaml.safe_load((REPO / "config/quick.yaml").read_text())["results"]
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(tmp_path)]
    proc = subprocess.run(
        [*cmd, "all", "table2_full", "table3_full", "-n", "--configfile", str(REPO / "config/quick.yaml")],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    outputs = [
        path
        for line in proc.stdout.splitlines()
        if line.strip().startswith(("output:", "log:", "benchmark:"))
        for path in line.split(":", 1)[1].replace(",", " ").split()
    ]
    assert outputs, proc.stdout[-2000:]
    under_full = [
        p for p in outputs if p.startswith(full_results + "/") and not p.startswith(quick_results + "/")
    ]
    assert not under_full, under_full[:10]


def test_every_mutant_still_applies_to_exactly_one_place():
    """`make mutants` puts each fault where its text stands once; a rename or an edit that moves the
    text makes the mutant silently inapplicable, so it is checked here, cheaply, on every run."""
    import mutants

    stale = [
        (m.name, m.path, (REPO / m.path).read_text().count(m.old) if (REPO / m.path).exists() else "missing")
        for m in mutants.MUTANTS
        if not (REPO / m.path).exists() or (REPO / m.path).read_text().count(m.old) != 1
    ]
    missing_tests = [
        (m.name, t) for m in mutants.MUTANTS for t in m.tests if not (REPO / t.split("::")[0]).exists()
    ]
    assert not stale and not missing_tests, (stale, missing_tests)
