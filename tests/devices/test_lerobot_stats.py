"""LeRobot's statistics (`devices/episodes/lerobot_stats.py`) at their edges, each worked
by hand: the quantile past the last bin, two rows against one, float64 values, a constant column whose float32
variance rounds below 0, the last axis of a 3-D feature, the frames sampled per episode and the downsampling of
video frames 300 pixels or more across."""
from __future__ import annotations

import numpy as np
import pytest

from touchanything.devices.episodes.lerobot_stats import _quantile, feature_stats, sample_indices, video_stats


def test_the_quantile_past_the_last_bin_is_the_last_edge():
    histogram, edges = np.array([1.0, 0.0, 1.0]), np.array([0.0, 1.0, 2.0, 3.0])  # cumulative 1, 1, 2
    assert _quantile(histogram, edges, 2.5) == 3.0  # more than the 2 values counted
    assert _quantile(histogram, edges, 0.5) == 0.0  # within the first bin: its lower edge (as LeRobot)
    assert _quantile(histogram, edges, 1.5) == 2.5  # past the empty bin: half-way through the third
    # cumulative 2, 4, 6: target 5 lies half-way through the third bin (4 counted before it, 2 in it)
    assert _quantile(np.array([2.0, 2.0, 2.0]), edges, 5.0) == 2.5


def test_two_rows_take_their_quantiles_from_the_histogram_and_one_row_its_own_values():
    """Rows 0 and 10 (float64): 5000 bins of width 0.002 from −1e-10 to 10 + 1e-10; q50 (target 1) is the first
    bin's lower edge, q99 (target 1.98) lies 0.98 of the way through the last bin: 9.998 + 0.98 · 0.002."""
    two = feature_stats(np.array([[0.0], [10.0]]))
    assert two["q50"] == pytest.approx([0.0], abs=1e-9) and two["q99"] == pytest.approx([9.99996], abs=1e-7)
    assert two["mean"].tolist() == [5.0] and two["std"].tolist() == [5.0]
    one = feature_stats(np.array([[3.0, 4.0]]))  # float64, one frame: LeRobot's quantiles are the values
    assert one["q01"].tolist() == [3.0, 4.0] and one["q99"].tolist() == [3.0, 4.0]
    assert one["min"].tolist() == [3.0, 4.0] and one["max"].tolist() == [3.0, 4.0] and one["count"].tolist() == [1]


def test_a_constant_column_has_std_0_where_float32_rounds_its_variance_below_0():
    values = np.full((5, 1), 0.7, np.float32)  # mean(x²) − mean² = −2.98e-08 in float32
    assert feature_stats(values)["std"].tolist() == [0.0]


def test_a_3d_feature_is_reduced_over_every_axis_but_the_last():
    values = np.arange(12, dtype=np.float32).reshape(2, 2, 3)  # rows [0 1 2] [3 4 5] [6 7 8] [9 10 11]
    stats = feature_stats(values)
    assert stats["mean"].tolist() == [4.5, 5.5, 6.5] and stats["min"].tolist() == [0.0, 1.0, 2.0]
    assert stats["count"].tolist() == [2]


def test_the_frames_sampled_per_episode():
    assert sample_indices(50).tolist() == list(range(50))  # under 100: every frame
    assert len(sample_indices(100)) == 100 and len(sample_indices(101)) == 100 and len(sample_indices(150)) == 100
    assert len(sample_indices(1000)) == 177  # int(1000 ** 0.75) = 177
    assert len(sample_indices(20_000)) == 1681 and len(sample_indices(10 ** 6)) == 10_000
    assert sample_indices(1000)[[0, -1]].tolist() == [0, 999]


@pytest.mark.parametrize(("height", "width", "step"), [(10, 300, 2), (300, 10, 2), (447, 10, 2), (10, 447, 2), (10, 299, 1),
                                                          (450, 10, 3)])
def test_video_frames_300_pixels_or_more_across_are_downsampled(height, width, step):
    """Bright lines every 4th pixel from 2 along the long side: every pixel kept sees a quarter of them bright, every
    2nd pixel (from 0) half, every 3rd a quarter (3k mod 4 runs through 0, 3, 2, 1)."""
    long = np.arange(max(height, width))
    line = np.where(long % 4 == 2, 255, 0).astype(np.uint8)
    frame = np.broadcast_to((line[:, None] if height > width else line[None, :])[..., None], (height, width, 3))
    mean = video_stats(frame[None])["mean"].ravel()
    kept = long[::step]
    assert mean == pytest.approx([np.mean(kept % 4 == 2)] * 3, abs=1e-6)
    assert mean[0] == pytest.approx({1: 0.25, 2: 0.5, 3: 0.25}[step], abs=0.01)
