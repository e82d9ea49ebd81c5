"""MkDocs hook: the notebooks live in notebooks/ (the pipeline runs them from there), outside
docs_dir; add their jupytext sources to the site as pages that mkdocs-jupyter renders."""

from pathlib import Path

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]


def on_files(files, config):
    # hooks run after the plugins' own on_files, so hand the new files to mkdocs-jupyter here
    jupyter = config.plugins["mkdocs-jupyter"]
    sources = sorted((ROOT / "notebooks").glob("*.py"))
    added = Files(
        [File(f"notebooks/{s.name}", str(ROOT), config.site_dir, config.use_directory_urls) for s in sources]
    )
    for file in jupyter.on_files(added, config):
        files.append(file)
    return files
