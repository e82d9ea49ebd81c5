"""Every file the pipeline writes under results/ is complete or absent: the scripts write through
``workflow/scripts/_pipeline.py`` (a temporary file beside the target, renamed only on success)."""

import ast
import sys

import pandas as pd
import pytest
from protocol import REPO

SCRIPTS = REPO / "workflow" / "scripts"
sys.path.insert(0, str(SCRIPTS))
import _pipeline  # noqa: E402


class Boom(RuntimeError):
    pass


def test_a_failed_write_leaves_the_previous_file_and_no_temporary(tmp_path):
    target = tmp_path / "tables" / "t.csv"
    _pipeline.write_text(target, "good\n")

    class Half(pd.DataFrame):
        def to_csv(self, path, **kwargs):
            with open(path, "w") as fh:
                fh.write("half a ta")
            raise Boom("disk full")

    with pytest.raises(Boom):
        _pipeline.write_csv(target, Half({"a": [1]}))
    assert target.read_text() == "good\n"
    assert [p.name for p in target.parent.iterdir()] == ["t.csv"]


def test_a_failed_first_write_leaves_nothing(tmp_path):
    target = tmp_path / "runs" / "x.npz"
    with pytest.raises(Boom):
        with _pipeline.atomic_path(target) as tmp:
            tmp.write_bytes(b"partial")
            raise Boom("killed")
    assert not target.exists() and not any(target.parent.iterdir())


def test_a_successful_write_is_readable_by_others(tmp_path):
    target = tmp_path / "t.md"
    _pipeline.write_text(target, "# table\n")
    assert target.read_text() == "# table\n" and target.stat().st_mode & 0o044 == 0o044


def _writes_to_outputs(path):
    """Calls in a script that write a file directly (not through _pipeline's helpers)."""
    direct = {"to_csv", "write_text", "write_bytes", "savefig", "savez", "savez_compressed", "dump", "open"}
    tree = ast.parse(path.read_text())
    allowed = set()
    for node in ast.walk(tree):  # calls on the temporary path of an atomic_path block are fine
        if isinstance(node, ast.With):
            for item in node.items:
                call = item.context_expr
                if isinstance(call, ast.Call) and getattr(call.func, "id", "") == "atomic_path":
                    allowed |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and id(node) not in allowed:
            name = getattr(node.func, "attr", getattr(node.func, "id", ""))
            if name not in direct or (isinstance(node.func, ast.Name) and name == "write_text"):
                continue  # not a write, or _pipeline's own write_text
            owner = getattr(node.func, "value", None)
            if name == "to_csv" and (
                (not node.args and "path_or_buf" not in {k.arg for k in node.keywords})
                or getattr(owner, "id", "") == "tables"  # nldr.tables.to_csv returns a string
            ):
                continue
            bad.append(f"{path.name}:{node.lineno} {name}")
    return bad


@pytest.mark.parametrize("script", sorted(p.name for p in SCRIPTS.glob("*.py") if p.name != "_pipeline.py"))
def test_scripts_write_only_through_the_atomic_helpers(script):
    assert _writes_to_outputs(SCRIPTS / script) == []
