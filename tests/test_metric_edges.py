"""Edges of the official metrics that the protocol tests do not pin, by value (found by mutation testing,
docs/testing.md): the ground truth clipped to [0, 1] whatever its scale, a frame decided by one cell, a frame of bend
cells only, values exactly at the threshold, exactly 5 % of the cells, no frame at all, no division by zero, and the
accumulator's short repr."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from touchanything.inference.evaluation.metrics import (
    CONTACT_THRESHOLD,
    MetricAccumulator,
    compute_tactile_metrics,
    contact_frames,
    ground_truth_for_metrics,
)


def test_the_ground_truth_is_clipped_to_zero_one_normalized_or_not():
    grids = np.full((1, 2, 21, 21), np.nan)
    grids[0, 0, 3, 3], grids[0, 0, 3, 4], grids[0, 1, 5, 5], grids[0, 1, 5, 6] = 1.5, -0.25, 0.5, 1.0
    normalized = ground_truth_for_metrics(grids, normalized=True)
    assert normalized.dtype == np.float64
    assert (normalized[0, 0, 3, 3], normalized[0, 0, 3, 4], normalized[0, 1, 5, 5], normalized[0, 1, 5, 6]) == (1.0, 0.0, 0.5, 1.0)
    assert np.isnan(normalized).sum() == 2 * 441 - 4
    scaled = ground_truth_for_metrics(grids, normalized=False)  # vmax = 1.5
    assert (scaled[0, 0, 3, 3], scaled[0, 0, 3, 4], scaled[0, 1, 5, 6]) == (1.0, 0.0, 1.0 / 1.5)
    small = ground_truth_for_metrics(grids * 0.5, normalized=False)  # max 0.75 < 1: vmax = 1, values kept
    assert (small[0, 0, 3, 3], small[0, 0, 3, 4], small[0, 1, 5, 6]) == (0.75, 0.0, 0.5)


BEND = np.zeros((2, 21, 21), bool)
BEND[0, 0, 0] = True
"""One bend cell, on the left hand."""


def blank(frames: int = 1) -> np.ndarray:
    return np.full((frames, 2, 21, 21), np.nan)


def test_one_valid_tactile_cell_decides_the_frame_alone():
    grids = blank()
    grids[0, 0, 5, 5] = 0.5  # 1 of 1 tactile cells above 0.1: 100 %
    assert contact_frames(grids, BEND).tolist() == [True]
    assert contact_frames(grids, BEND, min_ratio=0.6).tolist() == [True]
    metrics = compute_tactile_metrics(grids, grids, BEND, min_contact_ratio=0.6)
    assert (metrics["temporal_support"], metrics["temporal_recall"], metrics["temporal_accuracy"]) == (1, 1.0, 1.0)
    assert (metrics["contact_iou"], metrics["volumetric_iou"], metrics["mae"], metrics["mae_left"]) == (1.0, 1.0, 0.0, 0.0)
    assert np.isnan(metrics["mae_right"])
    grids[0, 1, 5, 5] = 0.0  # 1 of 2 cells: 50 %
    assert contact_frames(grids, BEND, min_ratio=0.6).tolist() == [False]
    assert compute_tactile_metrics(grids, grids, BEND, min_contact_ratio=0.6)["temporal_support"] == 0


def test_a_frame_whose_only_valid_cells_are_bend_cells_is_no_contact_even_at_ratio_zero():
    grids = blank()
    grids[0, 0, 0, 0] = 0.5
    assert contact_frames(grids, BEND, min_ratio=0.0).tolist() == [False]
    metrics = compute_tactile_metrics(grids, grids, BEND, min_contact_ratio=0.0)
    assert (metrics["temporal_support"], metrics["temporal_precision"], metrics["temporal_accuracy"]) == (0, 0.0, 1.0)
    assert metrics["contact_iou"] == 1.0  # bend cells count for the contact IoU
    grids[0, 1, 3, 3] = 0.0  # one tactile cell, not above: 0 % ≥ 0 % is contact
    assert contact_frames(grids, BEND, min_ratio=0.0).tolist() == [True]


@pytest.mark.parametrize("hand", [0, 1])
def test_a_ground_truth_or_a_prediction_exactly_at_the_threshold_is_not_on(hand):
    at, zero = blank(), blank()
    at[0, hand, 2:6, 2:7] = CONTACT_THRESHOLD  # 20 cells at exactly 0.1
    zero[0, hand, 2:6, 2:7] = 0.0
    for pred, gt in ((zero, at), (at, zero)):
        metrics = compute_tactile_metrics(pred, gt, BEND)
        assert np.isnan(metrics["contact_iou"]) and metrics["temporal_support"] == 0 and metrics["temporal_precision"] == 0.0
        assert metrics["volumetric_iou"] == 0.0 and metrics["mae"] == pytest.approx(0.1)
    assert contact_frames(at, BEND).tolist() == [False]
    above = np.where(np.isnan(at), np.nan, np.nextafter(CONTACT_THRESHOLD, 1.0))
    metrics = compute_tactile_metrics(zero, above, BEND)
    assert metrics["contact_iou"] == 0.0 and metrics["temporal_support"] == 1 and metrics["temporal_recall"] == 0.0


def test_the_accumulators_repr_leaves_out_the_contact_flags():
    accumulator = MetricAccumulator(BEND)
    accumulator.add(np.full((3, 2, 21, 21), 0.5), np.full((3, 2, 21, 21), 0.5))
    assert "kept_flags" not in repr(accumulator) and "sums" in repr(accumulator)


def test_no_frame_gives_no_flags():
    assert contact_frames(np.zeros((0, 2, 21, 21)), BEND).tolist() == []
    assert contact_frames(np.zeros((0, 2, 21, 21)), BEND, min_ratio=0.0).shape == (0,)


def test_exactly_five_percent_of_the_tactile_cells_is_contact():
    grids = blank()
    grids[0, 1, 0:4, 0:5] = 0.0  # 20 tactile cells, one above: 1 / 20 = 0.05 exactly
    grids[0, 1, 0, 0] = 0.5
    assert contact_frames(grids, BEND).tolist() == [True]
    assert compute_tactile_metrics(grids, grids, BEND)["temporal_support"] == 1
    grids[0, 1, 4, 0] = 0.0  # 1 / 21 < 0.05
    assert contact_frames(grids, BEND).tolist() == [False]
    assert compute_tactile_metrics(grids, grids, BEND)["temporal_support"] == 0


def test_frames_without_a_tactile_cell_divide_nothing_by_zero():
    grids = blank(3)
    grids[1, 0, 0, 0] = 0.5  # frame 1: a bend cell only; frames 0 and 2: no valid cell
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert contact_frames(grids, BEND).tolist() == [False, False, False]
        metrics = compute_tactile_metrics(grids, grids, BEND)
    assert metrics["temporal_support"] == 0 and metrics["temporal_accuracy"] == 1.0
