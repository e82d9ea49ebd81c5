"""nldr.plotting: the figures show every point and name every mark."""

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from nldr.experiments._mocap import Reconstructions  # noqa: E402
from nldr.plotting import _frame_numbers, figure1, figure3  # noqa: E402


def test_figure3_keeps_every_point_inside_its_panel_and_labels_the_axis():
    rows = []
    for std, scale in ((0.2, 1.0), (0.4, 3.0)):
        for rank in range(1, 31):
            err = scale * (0.1 + 0.9 / rank**2)  # rank 1 far above the rest, as KPCA's is
            rows.append((std, "KPCA", rank, err, err, err))
            rows.append((std, "CFS", rank, 0.9 * err, 0.8 * err, 1.2 * err))
    curves = pd.DataFrame(rows, columns=["noise_std", "method", "rank", "error", "error_min", "error_max"])
    fig = figure3(curves)
    for ax, std in zip(fig.axes, (0.2, 0.4), strict=True):
        sub = curves[curves["noise_std"] == std]
        lo, hi = ax.get_ylim()
        assert lo < sub[["error", "error_min"]].min().min() and hi > sub[["error", "error_max"]].max().max()
        assert ax.get_xlim()[1] > sub["rank"].max()
    assert "relative kernel error" in fig.axes[0].get_ylabel()
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "KPCA" in labels and any("over tau" in label for label in labels)


def test_figure1_legend_names_every_mark_and_titles_count_the_sequence_frames():
    rng = np.random.default_rng(0)
    F, P = 12, 5
    gt = rng.normal(size=(F, 3 * P))
    mask = rng.random((F, P)) < 0.5
    rec = Reconstructions(shapes={"TNH": gt + 0.1, "Kernel d_med": gt - 0.1}, mask=mask, ground_truth=gt)
    fig = figure1({"walk": rec}, {"walk": [(0, 1), (1, 2)]}, total_frames={"walk": 115})
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == [
        "ground truth (wire-frame)",
        "ground truth, observed",
        "ground truth, missing",
        "ours (Kernel d_med)",
        "TNH",
    ]
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[0].startswith("walk, frame ") and titles[0].endswith(" of 115")
    assert any("every 10th frame" in t.get_text() for t in fig.texts)


def test_frame_numbers_follow_every_sth_frame_from_the_first():
    for total, step in ((357, 10), (307, 10), (1102, 10), (100, 1), (50, 3)):
        shown = len(range(0, total, step))
        numbers, title, note = _frame_numbers(shown, total)
        assert list(numbers) == [f + 1 for f in range(0, total, step)] and title.endswith(f"of {total}")
    numbers, title, note = _frame_numbers(7, None)
    assert list(numbers) == list(range(1, 8)) and note == ""
