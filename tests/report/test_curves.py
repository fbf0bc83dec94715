"""The learning-curve plot: the frames axis counts the frames collected before training."""

from __future__ import annotations

import matplotlib.figure
import pytest

from torchrl_auv.report import plot_learning_curve


@pytest.fixture
def drawn(monkeypatch):
    """The figures ``plot_learning_curve`` saves, as ``[(xdata of each line, xlabel)]``."""
    figures = []

    def record(fig, *args, **kwargs):
        axes = fig.get_axes()
        figures.append(
            (
                [list(line.get_xdata()) for ax in axes for line in ax.get_lines()],
                axes[-1].get_xlabel(),
            )
        )

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", record)
    return figures


def test_the_axis_starts_after_the_offline_frames_and_says_so(tmp_path, drawn):
    curve = tmp_path / "train_curve.csv"
    curve.write_text("step,key,value\n1000,train/cost_mean,0.5\n2000,train/cost_mean,0.4\n")
    plot_learning_curve(curve, tmp_path / "plain.png")
    plot_learning_curve(curve, tmp_path / "offline.png", offline_frames=192000)
    (plain, plain_label), (shifted, label) = drawn
    assert plain == [[1000, 2000]] and plain_label == "frames"
    assert shifted == [[193000, 194000]] and "192,000 collected offline" in label
    with pytest.raises(ValueError, match="offline_frames must be an integer >= 0"):
        plot_learning_curve(curve, tmp_path / "bad.png", offline_frames=-1)
