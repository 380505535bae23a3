"""The official metric protocol on hand-computed examples, its 0/0 cases, and float64 accumulation."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from devices.tactile_layout import TactileLayout
from inference.metrics import MetricAccumulator, aggregate, compute_tactile_metrics, contact_frames, ground_truth_for_metrics

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
    assert all(math.isnan(v) for v in m.values())
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
