"""The experiment framework: one spread convention, the saved arrays' layout, jobs from the config."""

import io

import numpy as np
import pandas as pd
import pytest
from protocol import full_config, quick_config

from nldr.experiments import EXPERIMENTS, get, summary_stats
from nldr.experiments._mocap import Reconstructions, summarise_e3d
from nldr.experiments.base import SD_DDOF


def test_summary_stats_is_the_sample_sd_and_nan_for_one_replicate():
    v = np.array([1.0, 2.0, 4.0, np.nan])  # NaN: an unavailable run, dropped
    stats = summary_stats(v, "sse", extremes=True)
    x = v[~np.isnan(v)]
    assert SD_DDOF == 1
    assert stats["sse"] == pytest.approx(x.mean(), rel=1e-15)
    assert stats["sse_sd"] == pytest.approx(np.sqrt(np.sum((x - x.mean()) ** 2) / (len(x) - 1)), rel=1e-14)
    assert (stats["sse_min"], stats["sse_max"]) == (1.0, 4.0)
    one = summary_stats([3.0], "e3d")
    assert one["e3d"] == 3.0 and np.isnan(one["e3d_sd"]) and "e3d_min" not in one


def test_every_table_uses_the_same_sd_convention():
    runs = pd.DataFrame(
        {
            "sequence": ["yoga"] * 6,
            "missing_fraction": [0.5] * 6,
            "seed": [1, 1, 2, 2, 3, 3],
            "method": ["TNH", "Kernel d_med"] * 3,
            "e3d": [0.1, 0.08, 0.2, 0.15, 0.3, 0.2],
        }
    )
    table = summarise_e3d(runs)
    sd = table[(table["setting"] == "Yoga missing50") & (table["method"] == "TNH")]
    assert sd.set_index("metric")["value"]["e3d_sd"] == pytest.approx(np.std([0.1, 0.2, 0.3], ddof=1))
    table2 = get("table2").summarise(
        pd.DataFrame(
            {
                "p": [0.1] * 3,
                "seed": [1, 2, 3],
                "method": ["mean"] * 3,
                "sse": [10.0, 12.0, 17.0],
                "available": [True] * 3,
                "converged": [True] * 3,
            }
        )
    )
    got = table2.set_index("metric")["value"]["sse_sd"]
    assert got == pytest.approx(np.std([10.0, 12.0, 17.0], ddof=1))


def test_reconstructions_round_trip_through_npz():
    rng = np.random.default_rng(0)
    rec = Reconstructions(
        shapes={"TNH": rng.random((4, 9)), "Kernel d_med": rng.random((4, 9))},
        mask=rng.random((4, 3)) > 0.5,
        ground_truth=rng.random((4, 9)),
        cameras={"rigid": rng.random((4, 2, 3)), "TNH": rng.random((4, 2, 3))},
        extra={"tau_search": rng.random((5, 2))},
    )
    buffer = io.BytesIO()
    np.savez(buffer, **rec.to_arrays())
    buffer.seek(0)
    back = Reconstructions.from_arrays(np.load(buffer))
    assert list(back.shapes) == ["TNH", "Kernel d_med"]
    for name in rec.shapes:
        np.testing.assert_array_equal(back.shapes[name], rec.shapes[name])
    assert set(back.cameras) == {"rigid", "TNH"} and set(back.extra) == {"tau_search"}
    np.testing.assert_array_equal(back.mask, rec.mask)


@pytest.mark.parametrize("config", [full_config(), quick_config()], ids=["full", "quick"])
def test_jobs_follow_the_config(config):
    t1, t2, t3 = config["table1"], config["table2"], config["table3"]
    counts = {name: len(e.jobs(config)) for name, e in EXPERIMENTS.items()}
    assert counts["table1"] == len(t1["noise_std"]) * t1["n_draws"]
    for name in ("table2", "table2_full", "table2_all"):  # one job per p and group of masks
        s = EXPERIMENTS[name].settings(config)
        assert counts[name] == len(t2["p"]) * -(-s["n_masks"] // s.get("masks_per_job", 1)), name
    assert counts["table3"] == len(t3["sequences"]) * (1 + t3["n_seeds"])
    # table2_all: Ours takes the block's extra solver options on top of table2's
    assert EXPERIMENTS["table2_all"].settings(config)["ours"] == config["table2_all"]["ours"]
    # an inheriting experiment takes its parent's keys unless it sets them
    settings = EXPERIMENTS["table3_full"].settings(config)
    assert settings["step"] == config["table3_full"]["step"] and settings["tau"] == t3["tau"]
    # enumerating keys are not job settings: adding a seed reruns no existing job
    assert "n_masks" not in EXPERIMENTS["table2"].job_settings(config)
    # selection_nrsfm: per protocol, one full-data job and n_seeds masks per sequence, on that
    # table's masks (its seeds) and with that table's solver settings
    s = config["selection_nrsfm"]
    jobs = EXPERIMENTS["selection_nrsfm"].jobs(config)
    assert len(jobs) == sum(len(s["sequences"]) * (1 + s["n_seeds"][p]) for p in s["protocols"])
    for job in jobs:
        t = config[job.params["protocol"]]
        assert job.params["seed"] in range(
            t["seed"], t["seed"] + max(1, s["n_seeds"][job.params["protocol"]])
        )
    settings = EXPERIMENTS["selection_nrsfm"].job_settings(config)
    assert settings["table3"]["tau"] == t3["tau"] and "sequences" not in settings["table3"]


def test_unknown_names_are_reported_with_the_known_ones():
    with pytest.raises(ValueError, match="table1"):
        get("table9")
    with pytest.raises(ValueError, match="no job"):
        get("table1").job(full_config(), "std9_seed1")


def test_table2_rows_do_not_depend_on_how_masks_are_grouped_into_jobs(data_dir, monkeypatch):
    """Seven masks as one job each, as groups of three (3 + 3 + 1) and as one job: the same masks,
    seeds and rows (a peer limited to the first masks runs on exactly those)."""
    import nldr.experiments._table2 as module

    monkeypatch.setattr(
        module,
        "run_mask",
        lambda X, **kw: pd.DataFrame(
            {"p": [kw["p"]], "seed": [kw["seed"]], "method": ["Ours"], "sse": [1.0]}
        ),
    )
    config = full_config()
    config["table2"].update(n_rows=30, p=[0.1, 0.5], n_masks=7)
    config["table2"]["peers"] = {"methods": ["KNNImputer"], "n_folds": 2, "masks": {"KNNImputer": 4}}
    table2 = get("table2")
    tables = {}
    for per in (1, 3, 7):
        config["table2"]["masks_per_job"] = per
        jobs = table2.jobs(config)
        assert len(jobs) == 2 * -(-7 // per)
        assert len({job.id for job in jobs}) == len(jobs)
        settings = table2.job_settings(config)
        tables[per] = pd.concat([table2.run(job, settings, data_dir).rows for job in jobs], ignore_index=True)
    assert list(tables[1]["seed"].drop_duplicates()) == [config["table2"]["seed"] + k for k in range(7)]
    assert (tables[1]["method"] == "KNNImputer (CV)").sum() == 2 * 4
    for per in (3, 7):
        pd.testing.assert_frame_equal(tables[per].drop(columns="seconds"), tables[1].drop(columns="seconds"))


def test_table2_peers_follow_the_paper_rows_only_on_their_first_masks(data_dir, monkeypatch):
    """The peers add rows after the paper's (knobs by CV), a costly one only on the first masks per p,
    and leave the paper's rows as run_mask returns them (stubbed here: the peers are under test)."""
    import nldr.experiments._table2 as module

    paper_rows = pd.DataFrame(
        {
            "p": [0.1],
            "seed": [0],
            "method": ["Ours"],
            "sse": [1.0],
            "available": [True],
            "converged": [True],
            "n_iter": [3],
            "seconds": [0.0],
            "n_missing": [7],
        }
    )
    monkeypatch.setattr(module, "run_mask", lambda X, **kw: paper_rows.assign(seed=kw["seed"]))
    config = full_config()
    t2 = config["table2"]
    t2.update(n_rows=30, p=[0.1], n_masks=2, masks_per_job=1)
    t2["peers"] = {
        "methods": ["KNNImputer", "IterativeImputer", "missForest"],
        "n_folds": 2,
        "masks": {"missForest": 1},
        "missforest_trees": 10,
    }
    table2 = get("table2")
    settings = table2.job_settings(config)
    first, second = (table2.run(job, settings, data_dir).rows for job in table2.jobs(config))
    peers = ["KNNImputer (CV)", "IterativeImputer", "missForest (10 trees, CV)"]
    assert list(first["method"]) == ["Ours", *peers]
    assert list(second["method"]) == ["Ours", "KNNImputer (CV)", "IterativeImputer"]
    pd.testing.assert_frame_equal(first.iloc[:1][paper_rows.columns], paper_rows.assign(seed=t2["seed"]))
    knn = first.set_index("method").loc["KNNImputer (CV)"]
    assert knn["params"].startswith("{'n_neighbors'") and knn["available"] and knn["sse"] > 0
    assert first["n_missing"].nunique() == 2  # the stub's count, and the real mask's (same for every peer)
    table = table2.summarise(pd.concat([first, second]))
    assert list(dict.fromkeys(table["method"])) == ["Ours", *peers]
    n_masks = table[table["metric"] == "n_masks"].set_index("method")["value"]
    assert n_masks["missForest (10 trees, CV)"] == 1 and n_masks["KNNImputer (CV)"] == 2
    caption = table2.caption(config)
    assert "not in the paper" in caption and "missForest on the first 1 masks" in caption
    assert "10 trees per column (its authors recommend 100)" in caption
