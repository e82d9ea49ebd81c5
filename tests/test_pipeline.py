"""The pipeline end to end on the quick protocol, in a scratch working directory."""

import base64
import copy
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from protocol import QUICK, REPO, full_config, quick_config, quick_results, run_snakemake
from reproducible import compare_runs, output_files

from nldr.experiments import EXPERIMENTS
from nldr.experiments._table2 import PEER_ROWS
from nldr.experiments.base import is_measured
from nldr.tables import TABLE_COLUMNS

R = quick_results()  # e.g. results/quick
# every target of the quick protocol (the default target `all` is the same set)
TARGETS = [*"table1 fig3 table2 table3 fig1 table4 scorecard overview".split()]
TARGETS.append(f"{R}/notebooks/00_overview.html")  # the overview's HTML page, shown in the report


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    workdir = tmp_path_factory.mktemp("pipeline")
    proc = run_snakemake(
        workdir,
        *TARGETS,
        "-c",
        "2",
        "--configfile",
        str(QUICK),
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    return workdir


@pytest.mark.pipeline
def test_table1_target_builds_table_figure_and_notebook(quick_run):
    table = pd.read_csv(quick_run / R / "tables/table1.csv")
    assert list(table.columns) == TABLE_COLUMNS
    assert set(table["setting"]) == {"std=0.2", "std=0.3", "std=0.4"}
    published = table.dropna(subset=["paper"])
    assert len(published) == 12  # every number of the paper's Table 1 has ours beside it
    assert published["value"].notna().all()
    for ext in ("md", "html", "tex"):
        assert (quick_run / R / f"tables/table1.{ext}").stat().st_size > 0
    assert (quick_run / R / "figures/fig3.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (quick_run / R / "figures/fig3.pdf").read_bytes()[:5] == b"%PDF-"
    assert b"<svg" in (quick_run / R / "figures/fig3.svg").read_bytes()[:2000]
    notebook = quick_run / R / "notebooks/table1_robust_kpca.ipynb"
    assert notebook.is_file() and "Table 1" in notebook.read_text()
    for executed in (quick_run / R / "notebooks").glob("*.ipynb"):  # relative paths only
        text = executed.read_text()
        assert str(quick_run) not in text and str(REPO) not in text, executed.name
    assert not list((quick_run / "results").rglob(".*.tmp")) and not list(
        (quick_run / "results").rglob(".*.ipynb")
    )
    # the quick protocol wrote nothing outside its own folder
    outside = [p for p in (quick_run / "results").rglob("*") if p.is_file() and R not in str(p)]
    assert not outside, outside[:5]


@pytest.mark.pipeline
def test_second_run_has_nothing_to_do(quick_run):
    proc = run_snakemake(
        quick_run,
        *TARGETS,
        "-n",
        "--configfile",
        str(QUICK),
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Nothing to be done" in proc.stdout + proc.stderr


@pytest.mark.pipeline
def test_lint_is_clean(tmp_path):
    proc = run_snakemake(tmp_path, "--lint")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]


@pytest.mark.pipeline
def test_config_errors_are_caught_before_any_job(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("table1:\n  gamma: -1\n")
    proc = run_snakemake(tmp_path, "-n", "--configfile", str(bad))
    assert proc.returncode != 0
    assert "gamma" in proc.stdout + proc.stderr and not Path(tmp_path / "results").exists()


@pytest.mark.pipeline
def test_table2_target_has_every_method_beside_the_paper(quick_run):
    table = pd.read_csv(quick_run / R / "tables/table2.csv")
    assert list(table.columns) == TABLE_COLUMNS
    sse = table[table["metric"] == "sse"]
    # the paper's six rows and, not in the paper, the peers (missForest only on its first masks, with
    # 10 trees, which its label says: its authors recommend 100)
    peers = {m for m in PEER_ROWS if m != "missForest (CV)"}
    assert set(sse["method"]) == {"mean", "1-NN", "PPCA", "PKPCA", "RKPCA", "Ours", *peers}
    assert sse["paper"].notna().sum() >= 5 * len(set(sse["setting"]))
    assert (quick_run / R / "notebooks/table2_completion.ipynb").is_file()
    runs = pd.concat(pd.read_csv(p) for p in (quick_run / R / "runs/table2").glob("*.csv"))
    # every method saw the same mask within a run file
    assert runs.groupby(["p", "seed"])["n_missing"].nunique().eq(1).all()


@pytest.mark.pipeline
def test_table3_target_has_tnh_and_both_widths_beside_the_paper(quick_run):
    quick = quick_config()["table3"]
    table = pd.read_csv(quick_run / R / "tables/table3.csv")
    assert list(table.columns) == TABLE_COLUMNS
    e3d = table[table["metric"] == "e3d"]
    assert set(e3d["method"]) == {"TNH", "Kernel d_max", "Kernel d_med"}
    expected = {f"{s.capitalize()} {k}" for s in quick["sequences"] for k in ("full", "missing50")}
    assert set(e3d["setting"]) == expected | {"Mean full", "Mean missing50"}
    assert e3d["value"].notna().all() and (e3d["value"] > 0).all()
    assert e3d["paper"].notna().all()  # every cell we report has the paper's number beside it
    # the Mean row is the mean over the sequences of the per-sequence values
    for kind in ("full", "missing50"):
        for method in ("TNH", "Kernel d_med"):
            rows = e3d[(e3d["method"] == method) & e3d["setting"].str.endswith(kind)]
            per_seq = rows[~rows["setting"].str.startswith("Mean")]["value"]
            mean = rows[rows["setting"] == f"Mean {kind}"]["value"].item()
            assert mean == pytest.approx(per_seq.mean(), rel=1e-8)  # CSV keeps 10 digits
    assert (quick_run / R / "figures/fig1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (quick_run / R / "notebooks/table3_nrsfm.ipynb").is_file()


@pytest.mark.pipeline
def test_a_second_clean_run_on_one_core_gives_byte_identical_outputs(quick_run, tmp_path):
    """Every random draw is seeded, BLAS is pinned per job and the times a job measures are written
    apart (timings/), so every file under tables/, runs/ and figures/ (CSV, Markdown, HTML, LaTeX,
    NPZ, PNG, PDF, SVG) may not depend on the run or on how many jobs ran side by side (the first run
    used 2 cores, this one uses 1): the second run builds every such file of the first, byte for byte."""
    first = output_files(quick_run, R)
    built = [str(rel) for rel in first if rel.parts[len(Path(R).parts)] in ("tables", "figures")]
    assert {Path(p).parts[len(Path(R).parts)] for p in built} == {"tables", "figures"}
    # the timings really are apart: the first run wrote them, and no run or table file holds a time
    assert list((quick_run / R / "timings").rglob("*.csv"))
    for path in first.values():
        if path.suffix == ".csv":
            header = path.read_text().splitlines()[0].split(",")
            assert not [c for c in header if is_measured(c)], path
            if "tables" in path.parts:
                assert not pd.read_csv(path)["metric"].map(is_measured).any(), path
    proc = run_snakemake(tmp_path, *built, "-c", "1", "--configfile", str(QUICK))
    assert proc.returncode == 0, proc.stderr[-4000:]
    n_files, problems = compare_runs(quick_run, tmp_path, R)
    assert n_files == len(first)
    if problems:
        # name the BLAS kernels and CPU features each run's jobs used (see _pipeline.compute_fingerprint)
        seen = {
            f"{root.name}/{log.relative_to(root)}": line.split("compute:", 1)[1].strip()
            for root in (quick_run, tmp_path)
            for log in sorted((root / R / "logs").rglob("*.log"))
            for line in log.read_text().splitlines()
            if "compute:" in line
        }
        pytest.fail(
            f"{len(problems)} outputs differ between two clean runs: {problems}; compute per job: {seen}"
        )


@pytest.mark.pipeline
def test_changing_a_table2_parameter_reruns_table2_only(quick_run, tmp_path):
    config = yaml.safe_load(QUICK.read_text())
    config.setdefault("table2", {})["methods"] = {"Ours": {"tau": 0.2}}
    changed = tmp_path / "changed.yaml"
    changed.write_text(yaml.safe_dump(config, sort_keys=False))
    targets = ["table1", "fig3", "table2", "table3", "fig1"]
    proc = run_snakemake(quick_run, *targets, "-n", "--configfile", str(changed))
    assert proc.returncode == 0, proc.stderr[-2000:]
    outputs = [
        line.split(":", 1)[1].strip()
        for line in proc.stdout.splitlines()
        if line.strip().startswith("output:")
    ]
    planned = {Path(path).parent.name + "/" + Path(path).name for o in outputs for path in o.split(", ")}
    assert any(p.startswith("table2/") for p in planned)  # the runs of Table 2
    assert "tables/table2.csv" in planned and "notebooks/table2_completion.ipynb" in planned
    others = {p for p in planned if any(k in p for k in ("table1", "table3", "table4", "fig"))}
    assert not others, proc.stdout[-3000:]


@pytest.mark.pipeline
def test_scorecard_counts_match_the_tables(quick_run):
    """The report's headline counts, recomputed from the table CSVs with the bands' definitions."""
    bands = quick_config()["scorecard"]
    scored = pd.read_csv(quick_run / R / "scorecard.csv")
    published = 0
    for name in [e.name for e in EXPERIMENTS.values() if e.in_paper]:
        table = pd.read_csv(quick_run / R / f"tables/{name}.csv")
        headline = table[table["paper"].notna() & ~table["metric"].str.endswith(("_sd", "_min", "_max"))]
        published += len(headline)
        # spot-check the rel band of Table 1 against the CSV directly
        if name == "table1":
            rows = headline[headline["metric"] == "manifold_error"]
            expected = ((rows["value"] - rows["paper"]).abs() <= 0.05 * rows["paper"]).tolist()
            got = scored[(scored["table"] == name) & (scored["metric"] == "manifold_error")]["inside"]
            assert got.astype(bool).tolist() == expected
    assert len(scored) == published
    banded = scored[scored["inside"].notna()]
    inside = int(banded["inside"].astype(bool).sum())
    assert len(banded) >= sum(1 for b in bands if b["kind"] != "none")  # every banded rule scores a cell
    report = (quick_run / R / "report.md").read_text()
    assert f"**{inside} of {len(banded)} banded cells inside their band**; {published} numbers" in report
    assert "![fig3](figures/fig3.png)" in report and "git commit:" in report
    overview = (quick_run / R / "notebooks/00_overview.ipynb").read_text()
    assert f"{inside} of {len(banded)} banded cells inside their band" in overview


def report_entries(html: str) -> dict:
    """The results embedded in Snakemake's HTML report: path -> (mime type, decoded bytes)."""
    block = re.search(r"var results = (\{.*?\});\s*\n", html)
    assert block, "no results block in the report"
    entries = {}
    for path, entry in json.loads(block.group(1)).items():
        _, data = entry["data_uri"].split(",", 1)
        entries[path] = (entry["mime_type"], base64.b64decode(data))
    return entries


@pytest.mark.pipeline
def test_html_report_shows_every_table_figure_and_notebook_inline(quick_run):
    """Snakemake's report shows html/png inline and offers other types as downloads: every table, the
    scorecard and every executed notebook must be in it as HTML, every figure as PNG."""
    proc = run_snakemake(quick_run, "--report", f"{R}/report.html", "--configfile", str(QUICK))
    assert proc.returncode == 0, proc.stderr[-3000:]
    entries = report_entries((quick_run / R / "report.html").read_text(errors="replace"))
    paper = [e for e in EXPERIMENTS.values() if e.in_paper]
    for e in paper:
        mime, body = entries[f"{R}/tables/{e.name}.html"]
        page = body.decode()
        assert mime == "text/html" and page.count("<table") == 1 and "<td>" in page, e.name
        # the same cells as the CSV: every published number of ours is in the page, as the Markdown shows it
        md = (quick_run / R / f"tables/{e.name}.md").read_text()
        cells = {c.strip() for line in md.splitlines()[4:] if line.startswith("| ") for c in line.split("|")}
        assert all(f"<td>{c}</td>" in page for c in cells if c and c != "setting"), e.name
        if e.notebook:
            mime, body = entries[f"{R}/notebooks/{e.notebook}.html"]
            assert mime == "text/html" and b"jp-Notebook" in body and b"Traceback" not in body
    for figure in [f for e in paper for f in e.figures]:
        assert entries[f"{R}/figures/{figure}.png"][0] == "image/png"
    mime, body = entries[f"{R}/scorecard.html"]
    page = body.decode()
    assert mime == "text/html" and "banded cells inside their band" in page
    # every "why" link points inside the page (the notes are embedded), none into the checkout
    targets = set(re.findall(r'href="([^"]*)"', page))
    assert targets and all(t.startswith(("#", "http")) for t in targets), sorted(targets)[:5]
    anchors = set(re.findall(r'id="([^"]+)"', page))
    assert {t[1:] for t in targets if t.startswith("#")} <= anchors
    assert "../docs" not in page and f"{R}/notebooks/00_overview.html" in entries


@pytest.mark.pipeline
@pytest.mark.parametrize("profile", ["default", "slurm"])
def test_every_job_is_planned_with_each_profile(tmp_path, profile):
    """A dry run of the full protocol from nothing lists every job of every table with either profile."""
    proc = run_snakemake(tmp_path, "-n", "--profile", str(REPO / "profiles" / profile))
    assert proc.returncode == 0, proc.stderr[-3000:]
    config = full_config()
    t1, t2, t3, t4 = config["table1"], config["table2"], config["table3"], config["table4"]
    expected = {
        "run_job": len(t1["noise_std"]) * t1["n_draws"]
        + len(t2["p"]) * -(-t2["n_masks"] // t2.get("masks_per_job", 1))
        + len(t3["sequences"]) * (1 + t3["n_seeds"])
        + len(t4["sequences"]) * (1 + t4["n_seeds"]),
        "gather_table": 4,
        "draw_figure": 2,
        "notebook": 4,
        "notebook_html": 5,  # the four tables' notebooks and the overview
        "scorecard": 1,
        "all": 1,
    }
    counts = {}
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1].isdigit():
            counts.setdefault(parts[0], int(parts[1]))
    for rule, n in expected.items():
        assert counts.get(rule) == n, (rule, counts)


@pytest.mark.pipeline
def test_table4_target_has_tuned_tnh_and_both_widths_with_camera_errors(quick_run):
    quick = quick_config()["table4"]
    table = pd.read_csv(quick_run / R / "tables/table4.csv")
    assert list(table.columns) == TABLE_COLUMNS
    e3d = table[table["metric"] == "e3d"]
    assert set(e3d["method"]) == {"TNH", "Kernel d_max", "Kernel d_med"}
    assert e3d["paper"].notna().all() and (e3d["value"] > 0).all()
    runs = pd.concat(pd.read_csv(p) for p in (quick_run / R / "runs/table4").glob("*.csv"))
    assert len(runs) == 3 * len(quick["sequences"]) * (1 + quick["n_seeds"])
    lo, hi = quick["tnh"]["log10_tau_bounds"]
    tnh = runs[runs["method"] == "TNH"]
    assert ((np.log10(tnh["tau"]) >= lo - 1e-9) & (np.log10(tnh["tau"]) <= hi + 1e-9)).all()
    assert runs["camera_error"].notna().all() and runs["camera_error_init"].notna().all()
    assert (quick_run / R / "notebooks/table4_nrsfm_cameras.ipynb").is_file()


@pytest.mark.pipeline
def test_selection_target_keeps_cv_blind_and_labels_the_oracle(quick_run):
    proc = run_snakemake(quick_run, "selection", "-c", "2", "--configfile", str(QUICK))
    assert proc.returncode == 0, proc.stderr[-3000:]
    table = pd.read_csv(quick_run / R / "tables/selection.csv")
    assert list(table.columns) == TABLE_COLUMNS
    assert {"Ours (paper values)", "Ours (CV)", "Ours (oracle grid point)"} <= set(table["method"])
    runs = pd.concat(pd.read_csv(p) for p in (quick_run / R / "runs/selection").glob("*.csv"))
    grid = quick_config()["selection"]["grid"]["log10_tau"]
    taus = np.logspace(grid["min"], grid["max"], grid["num"])
    for _, job in runs.groupby(["p", "seed"]):
        by = job.set_index("method")
        # CV picks a grid point, and its refit is that grid point's solve: the oracle (the best grid
        # point on ground truth) can only be as good or better
        assert np.isclose(taus, by.loc["Ours (CV)", "tau"], rtol=1e-12).any()
        assert by.loc["Ours (oracle grid point)", "sse"] <= by.loc["Ours (CV)", "sse"] * (1 + 1e-12)
    assert (quick_run / R / "notebooks/selection.ipynb").is_file()


@pytest.mark.pipeline
def test_selection_full_target_builds_beyond_make_reproduce(quick_run):
    proc = run_snakemake(quick_run, "selection_full", "-c", "2", "--configfile", str(QUICK))
    assert proc.returncode == 0, proc.stderr[-3000:]
    table = pd.read_csv(quick_run / R / "tables/selection_full.csv")
    assert list(table.columns) == TABLE_COLUMNS and table["paper"].isna().all()
    s = {**quick_config()["selection"], **quick_config()["selection_full"]}
    assert {"Ours (paper values)", "Ours (CV)", "Ours (oracle grid point)"} <= set(table["method"])
    assert {f"{m} (CV)" for m in s["baselines"] if m != "IterativeImputer"} <= set(table["method"])
    runs = pd.concat(pd.read_csv(p) for p in (quick_run / R / "runs/selection_full").glob("*.csv"))
    assert len(runs.groupby(["p", "seed"])) == len(s["p"]) * s["n_masks"]
    for _, job in runs.groupby(["p", "seed"]):
        by = job.set_index("method")
        assert by.loc["Ours (oracle grid point)", "sse"] <= by.loc["Ours (CV)", "sse"]
    timings = pd.concat(pd.read_csv(p) for p in (quick_run / R / "timings/selection_full").glob("*.csv"))
    assert (timings["cpu_seconds"] > 0).all() and "cpu_seconds" not in runs
    makefile = (REPO / "Makefile").read_text()
    scale = next(line for line in makefile.splitlines() if line.startswith("\t") and "table3_full" in line)
    assert "selection_full" in scale  # in `make scale`, not in the default target


@pytest.mark.pipeline
def test_selection_nrsfm_target_keeps_cv_blind_and_gathers_the_oracle(quick_run):
    proc = run_snakemake(quick_run, "selection_nrsfm", "-c", "2", "--configfile", str(QUICK))
    assert proc.returncode == 0, proc.stderr[-3000:]
    table = pd.read_csv(quick_run / R / "tables/selection_nrsfm.csv")
    assert list(table.columns) == TABLE_COLUMNS
    methods = set(table["method"])
    assert {"Kernel (CV)", "TNH (CV tau)", "Kernel (CV) after TNH (CV tau)", "TNH (oracle tau*)"} <= methods
    runs = pd.concat(pd.read_csv(p) for p in (quick_run / R / "runs/selection_nrsfm").glob("*.csv"))
    s = quick_config()["selection_nrsfm"]
    g = s["tnh_grid"]["log10_tau"]
    tnh = runs[runs["method"] == "TNH (CV tau)"]
    assert (
        np.isclose(np.logspace(g["min"], g["max"], g["num"])[:, None], tnh["tau"].to_numpy())
        .any(axis=0)
        .all()
    )
    kernel = runs[runs["method"].str.startswith("Kernel (CV)")]
    assert kernel["tau"].isin(s["kernel_grid"]["taus"]).all()
    assert kernel["width_multiple"].isin(s["kernel_grid"]["width_multiples"]).all()
    # the oracle grid point: labelled, on the grid, and by construction never above the CV row (its
    # refit is the same solve at one grid point) nor the paper's d_med row (grid point (1e-4, 1))
    key = ["protocol", "sequence", "missing_fraction", "seed"]
    for _, job in runs.groupby(key):
        e = job.set_index("method")["e3d"]
        after = "" if job["protocol"].iloc[0] == "table3" else " after TNH (CV tau)"
        best = e[f"Kernel (oracle grid point){after}"]
        assert best <= e[f"Kernel (CV){after}"] * (1 + 1e-12) and best <= e[f"Kernel d_med{after}"] * (
            1 + 1e-12
        )
    # the paper-value rows are Table 3's runs on the same masks (same calls, same bits), and the
    # oracle rows are Table 4's own
    table3 = pd.concat(pd.read_csv(p) for p in (quick_run / R / "runs/table3").glob("*.csv"))
    key = ["sequence", "missing_fraction", "seed", "method"]
    ours = runs[runs["protocol"] == "table3"].astype({"missing_fraction": float})
    ours = ours.merge(table3.astype({"missing_fraction": float}), on=key, suffixes=("", "_table3"))
    assert len(ours) == 2 * len(runs[(runs["protocol"] == "table3") & (runs["method"] == "Kernel (CV)")])
    np.testing.assert_array_equal(ours["e3d"], ours["e3d_table3"])
    table4 = pd.concat(pd.read_csv(p) for p in (quick_run / R / "runs/table4").glob("*.csv"))
    oracle = table[(table["method"] == "TNH (oracle tau*)") & (table["metric"] == "e3d")]
    for seq in s["sequences"]:
        row = oracle[oracle["setting"] == f"Table 4 {seq.capitalize()} full"]
        expected = table4[
            (table4["sequence"] == seq) & (table4["missing_fraction"] == 0) & (table4["method"] == "TNH")
        ]
        assert row["value"].iloc[0] == expected["e3d"].iloc[0]
    assert (quick_run / R / "notebooks/selection_nrsfm.ipynb").is_file()


@pytest.mark.pipeline
def test_benchmark_target_builds_its_table_figure_and_notebook_outside_make_reproduce(tmp_path):
    # its own scratch folder (not the quick_run fixture): the target needs none of the paper's outputs.
    # The quick block's data sets, mechanisms and methods, on one mask of 30 rows each (a smaller
    # overlay of quick.yaml: the same plumbing, a third of the solves)
    s = copy.deepcopy(quick_config()["benchmark"])
    s["n_masks"] = 1
    s["datasets"] = [{**d, "n_rows": min(d.get("n_rows", 30), 30)} for d in s["datasets"]]
    small = tmp_path / "benchmark_small.yaml"
    small.write_text(yaml.safe_dump({"benchmark": s}, sort_keys=False))
    proc = run_snakemake(tmp_path, "benchmark", "-c", "2", "--configfile", str(QUICK), str(small))
    assert proc.returncode == 0, proc.stderr[-3000:]
    table = pd.read_csv(tmp_path / R / "tables/benchmark.csv")
    assert list(table.columns) == TABLE_COLUMNS and table["paper"].isna().all()
    assert set(table["method"]) == set(s["methods"])
    summary = table[table["setting"] == "all"]
    assert set(summary["metric"]) == {"mean_rank", "wins"}
    ranks = summary[summary["metric"] == "mean_rank"]["value"]
    n = len(s["methods"])
    assert ranks.between(1, n).all() and abs(ranks.sum() - n * (n + 1) / 2) < 1e-9  # ranks 1..n share out
    n_cells = len(s["datasets"]) * len(s["missingness"])
    assert summary[summary["metric"] == "wins"]["value"].sum() >= n_cells  # a tie gives each a win
    runs = pd.concat(pd.read_csv(p) for p in (tmp_path / R / "runs/benchmark").glob("*.csv"))
    assert len(runs) == n_cells * s["n_masks"] * n and "cpu_seconds" not in runs  # timings: apart
    timing_arrays = sorted((tmp_path / R / "timings/benchmark").glob("*.npz"))
    assert len(timing_arrays) == n_cells
    for npz in timing_arrays:
        with np.load(npz) as arrays:
            assert (arrays["cpu_seconds"] > 0).all() and (arrays["tune_cpu_seconds"] >= 0).all()
    for npz in (tmp_path / R / "runs/benchmark").glob("*.npz"):
        with np.load(npz) as arrays:
            assert "cpu_seconds" not in arrays and "tune_methods" in arrays
    assert (tmp_path / R / "figures/benchmark_ranks.png").is_file()
    assert (tmp_path / R / "notebooks/benchmark.ipynb").is_file()
    makefile = (REPO / "Makefile").read_text().splitlines()
    reproduce = next(line for line in makefile if line.startswith("reproduce:"))
    assert "benchmark" not in reproduce and not EXPERIMENTS["benchmark"].in_paper  # not in `all`
