"""Write the scorecard (nldr.scorecard) with the figures and a provenance block: results/report.md
(Markdown, links into the checkout's docs/) and results/scorecard.html (a standalone page for the HTML
report: figures embedded, docs/REPRODUCTION.md embedded as an appendix that the cells link to, so
every link works outside the repository)."""

import base64
import hashlib
import json
import os
import platform
import re
import subprocess
from importlib import metadata
from pathlib import Path

import mistune
import pandas as pd
from _pipeline import setup, write_text

from nldr import scorecard
from nldr.datasets import FILES
from nldr.tables import html_page

sm = snakemake  # noqa: F821
log = setup(sm)
out_dir = Path(sm.output.md).parent

tables = {Path(p).stem: pd.read_csv(p) for p in sm.input.tables}
scored = scorecard.score(tables, sm.params.bands)
total = scorecard.counts(scored)
write_text(sm.output.csv, scored.to_csv(index=False, float_format="%.10g"))


def git_commit(repo):
    try:
        commit = subprocess.run(
            ["git", "-C", repo, "rev-parse", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
        status = ["git", "-C", repo, "status", "--porcelain", "--untracked-files=no"]
        dirty = subprocess.run(status, capture_output=True, text=True).stdout.strip()
        return commit + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"


def wall_times():
    rows = []
    for tsv in sorted(Path(sm.params.benchmarks).glob("*/*.tsv")):
        frame = pd.read_csv(tsv, sep="\t")
        rows.append({"experiment": tsv.parent.name, "jobs": 1, "seconds": float(frame["s"].iloc[-1])})
    if not rows:
        return "no benchmark files found\n"
    agg = (
        pd.DataFrame(rows)
        .groupby("experiment")
        .agg(jobs=("jobs", "sum"), seconds=("seconds", "sum"), longest=("seconds", "max"))
    )
    lines = ["| experiment | jobs | total seconds | longest job (s) |", "|---|---|---|---|"]
    lines += [f"| {name} | {int(r.jobs)} | {r.seconds:.1f} | {r.longest:.1f} |" for name, r in agg.iterrows()]
    return "\n".join(lines) + "\n"


config_json = json.dumps(sm.params.config, sort_keys=True, default=str)
config_hash = hashlib.sha256(config_json.encode()).hexdigest()[:16]
doc_link = os.path.relpath(Path(sm.params.repo) / "docs/REPRODUCTION.md", out_dir)
packages = ["numpy", "scipy", "scikit-learn", "cvxpy", "pandas", "matplotlib", "snakemake", "nldr"]
versions = ", ".join(f"{p} {metadata.version(p)}" for p in packages)
# the fetch rule verified every input against its pinned sha256, so the pins are the files' hashes
relpaths = [f"{Path(p).parent.name}/{Path(p).name}" for p in sm.input.data]
data = "\n".join(f"| `{rel}` | `{FILES[rel].sha256}` |" for rel in relpaths)


def page(doc_link, figures, notes=""):
    return f"""# Reproduction scorecard

**{total["inside"]} of {total["banded"]} banded cells inside their band**; {total["cells"]} numbers
published in the reproduced tables, {total["cells"] - total["banded"]} of them shown without a band.
Bands are the ones agreed for each table (config key `scorecard`); every cell links to the section of
docs/REPRODUCTION.md that explains its protocol and any gap. As data: `scorecard.csv` beside this file.

{scorecard.to_markdown(scored, doc_link=doc_link)}
## Figures

{figures}

## Provenance

- git commit: `{git_commit(sm.params.repo)}`
- config sha256 (first 16 hex digits): `{config_hash}`
- packages: {versions}
- machine: {platform.platform()}, Python {platform.python_version()}, {os.cpu_count()} CPUs

| data file | sha256 |
|---|---|
{data}

Wall time per experiment's jobs (from Snakemake's `benchmark:` files):

{wall_times()}{notes}"""


def embedded_notes(path):
    """docs/REPRODUCTION.md as an appendix: its anchors are the cells' link targets; links to other
    files of docs/ become plain text (they would not resolve outside the checkout)."""
    text = re.sub(r"\A# [^\n]*\n", "", Path(path).read_text())  # its title: the appendix heading below
    text = re.sub(r"\[([^\]]+)\]\((?!#|https?:)([^)]+)\)", r"\1 (`docs/\2`)", text)
    text = re.sub(r"^(#{1,5}) ", r"#\1 ", text, flags=re.M)  # one level below this page's sections
    return "\n\n## Appendix: reproduction notes (docs/REPRODUCTION.md of this commit)\n\n" + text


def embedded_figure(path):
    encoded = base64.b64encode(Path(path).read_bytes()).decode()
    return f'<img alt="{Path(path).stem}" src="data:image/png;base64,{encoded}" style="max-width:100%">'


figures_md = "\n\n".join(f"![{Path(f).stem}]({os.path.relpath(f, out_dir)})" for f in sm.input.figures)
write_text(sm.output.md, page(doc_link, figures_md))
figures_html = "\n\n".join(embedded_figure(f) for f in sm.input.figures)
body = mistune.create_markdown(escape=False, plugins=["table"])(
    page("", figures_html, embedded_notes(sm.input.docs))
)
write_text(sm.output.html, html_page("Reproduction scorecard", body))
log.info("scorecard: %d of %d banded cells inside", total["inside"], total["banded"])
