"""The official metric protocol on hand-computed examples, its 0/0 cases, and float64 accumulation; the
unreported contact-timing metrics (frame precision / recall / F1, onsets and offsets) on hand-made contact
sequences; and the metrics at their edges, by value: the ground truth clipped to [0, 1] whatever its scale, a frame
decided by one cell, a frame of bend cells only, values exactly at the threshold, exactly 5 % of the cells, no frame
at all, no division by zero, and the accumulator's short repr."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from touchanything.core.tactile_layout import TactileLayout
from touchanything.inference.evaluation.metrics import (
    ALL_METRICS,
    CONTACT_THRESHOLD,
    MetricAccumulator,
    aggregate,
    compute_tactile_metrics,
    contact_frames,
    ground_truth_for_metrics,
    matched_events,
)

LAYOUT = TactileLayout.default()
BEND = LAYOUT.bend


def empty(frames: int) -> np.ndarray:
    """(frames, 2, 21, 21) zeros inside the layout, NaN outside."""
    return np.repeat(LAYOUT.nan_mask()[None], frames, axis=0).astype(np.float64)


def tactile_cells(hand: int, count: int) -> list[tuple[int, int]]:
    return [tuple(rc) for rc in np.argwhere(LAYOUT.tactile[hand])[:count]]


def test_worked_example_from_the_reference():
    gt, pred = empty(2), empty(2)
    cells = tactile_cells(0, 3)
    gt[0, 0][cells[0]] = pred[0, 0][cells[0]] = 0.5
    for cell in cells:
        gt[1, 0][cell] = 0.5
    m = compute_tactile_metrics(pred, gt, BEND)
    assert m["contact_iou"] == pytest.approx(0.25)
    assert m["volumetric_iou"] == pytest.approx(0.25)
    assert m["mae"] == pytest.approx(1.5 / (2 * 434))
    assert m["temporal_accuracy"] == 1.0
    assert m["mae_right"] == 0.0 and m["mae_left"] == pytest.approx(1.5 / (2 * 217))


def test_contact_needs_16_of_302_tactile_cells_and_ignores_bend_cells():
    grids = empty(4)
    for hand in (0, 1):
        grids[1, hand][LAYOUT.bend[hand]] = 1.0  # bend only: never contact
    for k, cell in enumerate(tactile_cells(0, 16)):
        grids[2, 0][cell] = 0.5
        if k < 15:
            grids[3, 0][cell] = 0.5
    grids[3, 0][tactile_cells(0, 16)[15]] = 0.1  # exactly 0.1 is not above the threshold
    assert contact_frames(grids, BEND).tolist() == [False, False, True, False]
    assert int((~BEND & LAYOUT.valid).sum()) == 302


def test_zero_over_zero_cases_follow_the_protocol():
    zeros = empty(3)
    m = compute_tactile_metrics(zeros, zeros, BEND)
    assert math.isnan(m["contact_iou"]) and math.isnan(m["volumetric_iou"])
    assert m["temporal_accuracy"] == 1.0 and m["mae"] == 0.0
    all_nan = np.full((2, 2, 21, 21), np.nan)
    m = compute_tactile_metrics(np.zeros_like(all_nan), all_nan, BEND)
    counts = ("temporal_support", "num_gt_onsets", "num_gt_offsets")
    assert all(math.isnan(m[k]) for k in ALL_METRICS if k not in counts) and all(m[k] == 0 for k in counts)
    assert math.isnan(aggregate([m, m])["mae"])
    assert aggregate([{**m, "mae": 0.2}, {**m, "mae": 0.4}])["mae"] == pytest.approx(0.3)


def test_prediction_is_masked_by_ground_truth_nan():
    gt, pred = empty(1), np.ones((1, 2, 21, 21))
    m = compute_tactile_metrics(pred, gt, BEND)
    assert m["mae"] == 1.0 and m["contact_iou"] == 0.0 and m["volumetric_iou"] == 0.0


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 6), st.integers(0, 2**31 - 1), st.integers(1, 5))
def test_streaming_accumulation_equals_one_batch(frames, seed, chunks):
    rng = np.random.default_rng(seed)
    gt = empty(frames) + rng.random((frames, 2, 21, 21)) * (rng.random((frames, 2, 21, 21)) < 0.3)
    pred = rng.random((frames, 2, 21, 21))
    batch = compute_tactile_metrics(pred, gt, BEND)
    acc = MetricAccumulator(BEND)
    for part in np.array_split(np.arange(frames), chunks):
        acc.add(pred[part], gt[part])
    streamed = acc.result()
    for key, value in batch.items():
        assert (math.isnan(value) and math.isnan(streamed[key])) or streamed[key] == pytest.approx(value, rel=1e-12)


def test_float64_accumulation_stays_exact_over_a_million_frames():
    gt, pred = (empty(10_000) + 0.5).astype(np.float32), (empty(10_000) + 0.3).astype(np.float32)
    acc = MetricAccumulator(BEND)
    for _ in range(100):
        acc.add(pred, gt)
    result = acc.result()
    low = float(np.float32(0.3))
    assert acc.sums["cells_left"] == 1_000_000 * 217 and acc.sums["judged"] == 1_000_000
    assert result["volumetric_iou"] == pytest.approx(low / 0.5, rel=1e-12)
    assert result["mae"] == pytest.approx(0.5 - low, rel=1e-12)
    assert result["contact_iou"] == 1.0 and result["temporal_accuracy"] == 1.0
    float32_sum = np.float32(0.0)
    for _ in range(100):  # what a float32 running sum would have given
        float32_sum += np.nansum(np.abs(pred - gt)[:, 0], dtype=np.float32)
    assert abs(float(float32_sum) / (1_000_000 * 217) - (0.5 - low)) > 1e-9


def test_ground_truth_vmax_fallback():
    grids = empty(2)
    grids[0, 0, 2, 1] = 4.0
    assert np.nanmax(ground_truth_for_metrics(grids, normalized=False)) == 1.0
    assert ground_truth_for_metrics(grids, normalized=False)[0, 0, 2, 2] == 0.0
    assert np.nanmax(ground_truth_for_metrics(grids * 0.1, normalized=False)) == pytest.approx(0.4)
    assert np.isnan(ground_truth_for_metrics(grids, normalized=True)[0, 0, 0, 0])
    assert np.isnan(ground_truth_for_metrics(np.full((1, 2, 21, 21), np.nan), normalized=False)).all()


def sequence(flags: str) -> np.ndarray:
    """Frames from a string: "1" contact (16 tactile cells at 0.5), "0" no contact, "n" all NaN."""
    grids = empty(len(flags))
    rows, cols = np.array(tactile_cells(0, 16)).T
    for i, flag in enumerate(flags):
        if flag == "1":
            grids[i, 0, rows, cols] = 0.5
        elif flag == "n":
            grids[i] = np.nan
    return grids


def timing(pred: str, gt: str) -> dict[str, float]:
    return compute_tactile_metrics(sequence(pred), sequence(gt), BEND)


def events(m: dict[str, float]) -> tuple:
    return (m["onset_precision"], m["onset_recall"], m["num_gt_onsets"],
            m["offset_precision"], m["offset_recall"], m["num_gt_offsets"])


@pytest.mark.parametrize("pred, gt, want", [
    ("0000011111", "0001111111", (1.0, 1.0, 1, 0.0, 0.0, 0)),  # onset 2 frames late: matched
    ("0111111111", "0001111111", (1.0, 1.0, 1, 0.0, 0.0, 0)),  # 2 frames early: matched
    ("0000001111", "0001111111", (0.0, 0.0, 1, 0.0, 0.0, 0)),  # 3 frames late: not
    ("1111110000", "1111000000", (0.0, 0.0, 0, 1.0, 1.0, 1)),  # offset 2 frames late: matched
    ("1111111000", "1111000000", (0.0, 0.0, 0, 0.0, 0.0, 1)),  # 3 frames late: not
    ("0110011000", "0110000000", (0.5, 1.0, 1, 0.5, 1.0, 1)),  # one extra predicted press
])
def test_onsets_and_offsets_match_within_two_frames(pred, gt, want):
    assert events(timing(pred, gt)) == want


def test_no_ground_truth_events_and_no_predicted_events_give_zero():
    assert events(timing("1100", "1111")) == (0.0, 0.0, 0, 0.0, 0.0, 0)  # a predicted offset, none true
    assert events(timing("0000", "0011")) == (0.0, 0.0, 1, 0.0, 0.0, 0)  # a true onset, none predicted
    assert events(timing("0000", "0000")) == (0.0, 0.0, 0, 0.0, 0.0, 0)
    assert events(timing("0110", "0000")) == (0.0, 0.0, 0, 0.0, 0.0, 0)  # predicted events, no true ones
    assert events(timing("0n0", "0n0")) == events(timing("0nn0", "nn00")) == (0.0, 0.0, 0, 0.0, 0.0, 0)  # 2 kept


def test_all_nan_frames_are_removed_from_the_event_sequence():
    # kept frames: ground truth 0111, prediction 0011: onsets at kept positions 1 and 2 (frames 1 and 5)
    assert events(timing("00nnn11", "01nnn11")) == (1.0, 1.0, 1, 0.0, 0.0, 0)
    # a NaN frame inside a press is neither an offset nor an onset
    assert events(timing("1n1", "1n1")) == (0.0, 0.0, 0, 0.0, 0.0, 0)


@pytest.mark.parametrize("gt", ["", "n", "1", "n1n", "0nn"])
def test_fewer_than_two_kept_frames_give_nan_event_ratios_and_zero_counts(gt):
    m = timing("1" * len(gt), gt)
    assert all(math.isnan(m[f"{kind}_{ratio}"]) for kind in ("onset", "offset") for ratio in ("precision", "recall"))
    assert m["num_gt_onsets"] == 0 and m["num_gt_offsets"] == 0


def test_frame_precision_recall_f1_by_hand():
    m = timing("0111110", "1111000")  # TP 3, FP 2, FN 1
    assert m["temporal_precision"] == pytest.approx(3 / 5) and m["temporal_recall"] == pytest.approx(3 / 4)
    assert m["temporal_f1"] == pytest.approx(2 * 0.6 * 0.75 / 1.35) and m["temporal_support"] == 4
    assert m["temporal_accuracy"] == pytest.approx(4 / 7)
    m = timing("00n", "11n")  # nothing predicted: precision's denominator is 0
    assert (m["temporal_precision"], m["temporal_recall"], m["temporal_f1"], m["temporal_support"]) == (0.0, 0.0, 0.0, 2)


def detection(m: dict[str, float]) -> tuple:
    return m["temporal_precision"], m["temporal_recall"], m["temporal_f1"], m["temporal_support"]


@pytest.mark.parametrize("pred, gt", [("110", "000"), ("000", "000"), ("1n0", "0n0"), ("0", "0"), ("1nn", "0nn")])
def test_valid_frames_without_ground_truth_contact_give_zeros_as_the_official_function(pred, gt):
    """official temporal_f1_score: precision tp/(tp+fp) or 0.0 when nothing is predicted, recall 0.0, F1 0.0"""
    assert detection(timing(pred, gt)) == (0.0, 0.0, 0.0, 0)


@pytest.mark.parametrize("pred, gt", [("", ""), ("1", "n"), ("0n", "nn"), ("111", "nnn")])
def test_no_valid_ground_truth_frame_gives_nan_precision_recall_f1(pred, gt):
    m = timing(pred, gt)
    assert all(math.isnan(m[k]) for k in ("temporal_precision", "temporal_recall", "temporal_f1"))
    assert m["temporal_support"] == 0


def test_a_contact_free_trajectory_counts_as_zero_in_the_average():
    out = aggregate([timing("0011", "0011"), timing("1100", "0000"), timing("nn", "nn")])
    assert out["temporal_f1"] == pytest.approx(0.5) and out["temporal_precision"] == pytest.approx(0.5)
    assert out["temporal_support"] == pytest.approx(2 / 3)


def test_a_predicted_event_takes_the_first_unmatched_true_event():
    assert matched_events(np.array([4, 6]), np.array([2, 4])) == 2  # 4 takes 2 (first in range), 6 takes 4
    assert matched_events(np.array([3, 4]), np.array([3])) == 1  # a true event matches once
    assert matched_events(np.array([], int), np.array([3])) == 0


def test_aggregate_averages_the_extra_metrics_and_counts():
    rows = [timing("0011", "0011"), timing("0000", "0111"), timing("n", "n")]
    out = aggregate(rows)
    assert tuple(out) == ALL_METRICS
    assert out["num_gt_onsets"] == pytest.approx(2 / 3) and out["onset_recall"] == pytest.approx(0.5)
    assert out["temporal_f1"] == pytest.approx(0.5)


@settings(max_examples=60, deadline=None)
@given(st.text("01n", max_size=12), st.text("01n", max_size=12), st.lists(st.integers(0, 12), max_size=4))
def test_chunked_accumulation_of_contact_sequences_equals_one_call(pred, gt, cuts):
    frames = min(len(pred), len(gt))
    p, g = sequence(pred[:frames]), sequence(gt[:frames])
    acc = MetricAccumulator(BEND)
    for part in np.split(np.arange(frames), sorted(min(c, frames) for c in cuts)):
        acc.add(p[part], g[part])
    streamed, batch = acc.result(), compute_tactile_metrics(p, g, BEND)
    assert tuple(streamed) == ALL_METRICS
    assert all(streamed[k] == batch[k] or (math.isnan(streamed[k]) and math.isnan(batch[k])) for k in ALL_METRICS)


# --- edges the protocol tests above do not pin, by value -----------------------------------------------------------------
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


ONE_BEND_CELL = np.zeros((2, 21, 21), bool)
ONE_BEND_CELL[0, 0, 0] = True
"""One bend cell, on the left hand."""


def blank(frames: int = 1) -> np.ndarray:
    return np.full((frames, 2, 21, 21), np.nan)


def test_one_valid_tactile_cell_decides_the_frame_alone():
    grids = blank()
    grids[0, 0, 5, 5] = 0.5  # 1 of 1 tactile cells above 0.1: 100 %
    assert contact_frames(grids, ONE_BEND_CELL).tolist() == [True]
    assert contact_frames(grids, ONE_BEND_CELL, min_ratio=0.6).tolist() == [True]
    metrics = compute_tactile_metrics(grids, grids, ONE_BEND_CELL, min_contact_ratio=0.6)
    assert (metrics["temporal_support"], metrics["temporal_recall"], metrics["temporal_accuracy"]) == (1, 1.0, 1.0)
    assert (metrics["contact_iou"], metrics["volumetric_iou"], metrics["mae"], metrics["mae_left"]) == (1.0, 1.0, 0.0, 0.0)
    assert np.isnan(metrics["mae_right"])
    grids[0, 1, 5, 5] = 0.0  # 1 of 2 cells: 50 %
    assert contact_frames(grids, ONE_BEND_CELL, min_ratio=0.6).tolist() == [False]
    assert compute_tactile_metrics(grids, grids, ONE_BEND_CELL, min_contact_ratio=0.6)["temporal_support"] == 0


def test_a_frame_whose_only_valid_cells_are_bend_cells_is_no_contact_even_at_ratio_zero():
    grids = blank()
    grids[0, 0, 0, 0] = 0.5
    assert contact_frames(grids, ONE_BEND_CELL, min_ratio=0.0).tolist() == [False]
    metrics = compute_tactile_metrics(grids, grids, ONE_BEND_CELL, min_contact_ratio=0.0)
    assert (metrics["temporal_support"], metrics["temporal_precision"], metrics["temporal_accuracy"]) == (0, 0.0, 1.0)
    assert metrics["contact_iou"] == 1.0  # bend cells count for the contact IoU
    grids[0, 1, 3, 3] = 0.0  # one tactile cell, not above: 0 % ≥ 0 % is contact
    assert contact_frames(grids, ONE_BEND_CELL, min_ratio=0.0).tolist() == [True]


@pytest.mark.parametrize("hand", [0, 1])
def test_a_ground_truth_or_a_prediction_exactly_at_the_threshold_is_not_on(hand):
    at, zero = blank(), blank()
    at[0, hand, 2:6, 2:7] = CONTACT_THRESHOLD  # 20 cells at exactly 0.1
    zero[0, hand, 2:6, 2:7] = 0.0
    for pred, gt in ((zero, at), (at, zero)):
        metrics = compute_tactile_metrics(pred, gt, ONE_BEND_CELL)
        assert np.isnan(metrics["contact_iou"]) and metrics["temporal_support"] == 0 and metrics["temporal_precision"] == 0.0
        assert metrics["volumetric_iou"] == 0.0 and metrics["mae"] == pytest.approx(0.1)
    assert contact_frames(at, ONE_BEND_CELL).tolist() == [False]
    above = np.where(np.isnan(at), np.nan, np.nextafter(CONTACT_THRESHOLD, 1.0))
    metrics = compute_tactile_metrics(zero, above, ONE_BEND_CELL)
    assert metrics["contact_iou"] == 0.0 and metrics["temporal_support"] == 1 and metrics["temporal_recall"] == 0.0


def test_the_accumulators_repr_leaves_out_the_contact_flags():
    accumulator = MetricAccumulator(ONE_BEND_CELL)
    accumulator.add(np.full((3, 2, 21, 21), 0.5), np.full((3, 2, 21, 21), 0.5))
    assert "kept_flags" not in repr(accumulator) and "sums" in repr(accumulator)


def test_no_frame_gives_no_flags():
    assert contact_frames(np.zeros((0, 2, 21, 21)), ONE_BEND_CELL).tolist() == []
    assert contact_frames(np.zeros((0, 2, 21, 21)), ONE_BEND_CELL, min_ratio=0.0).shape == (0,)


def test_exactly_five_percent_of_the_tactile_cells_is_contact():
    grids = blank()
    grids[0, 1, 0:4, 0:5] = 0.0  # 20 tactile cells, one above: 1 / 20 = 0.05 exactly
    grids[0, 1, 0, 0] = 0.5
    assert contact_frames(grids, ONE_BEND_CELL).tolist() == [True]
    assert compute_tactile_metrics(grids, grids, ONE_BEND_CELL)["temporal_support"] == 1
    grids[0, 1, 4, 0] = 0.0  # 1 / 21 < 0.05
    assert contact_frames(grids, ONE_BEND_CELL).tolist() == [False]
    assert compute_tactile_metrics(grids, grids, ONE_BEND_CELL)["temporal_support"] == 0


def test_frames_without_a_tactile_cell_divide_nothing_by_zero():
    grids = blank(3)
    grids[1, 0, 0, 0] = 0.5  # frame 1: a bend cell only; frames 0 and 2: no valid cell
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert contact_frames(grids, ONE_BEND_CELL).tolist() == [False, False, False]
        metrics = compute_tactile_metrics(grids, grids, ONE_BEND_CELL)
    assert metrics["temporal_support"] == 0 and metrics["temporal_accuracy"] == 1.0
