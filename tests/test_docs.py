"""The documentation site builds without a warning (mkdocs --strict), with an API page per module
documented and a page per notebook."""

import os
import subprocess
import sys

import pytest
from protocol import REPO

pytest.importorskip("mkdocs", reason="the docs extra (make setup installs it with .[dev])")


def test_docs_build_strictly_with_api_and_notebook_pages(tmp_path):
    site = tmp_path / "site"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "mkdocs",
            "build",
            "--strict",
            "-f",
            str(REPO / "mkdocs.yml"),
            "-d",
            str(site),
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "WARNING" not in proc.stderr, proc.stderr[-3000:]
    api = (site / "api/model_selection/index.html").read_text()
    # numpydoc sections rendered from the docstrings, Sphinx roles resolved to names
    assert 'id="nldr.model_selection.HoldoutSearch"' in api and "Parameters:" in api
    assert ":func:" not in api
    for notebook in sorted((REPO / "notebooks").glob("*.py")):
        page = site / "notebooks" / notebook.stem / "index.html"
        assert page.is_file() and "jp-Notebook" in page.read_text(), notebook.name
