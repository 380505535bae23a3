"""The official contact threshold pinned on both sides: a cell is "in contact" when strictly above 0.1 (0.1 itself
is not, 0.1001 is, 0.0999 is not), and a frame is when at least 5 % of its non-NaN non-bend cells are (16 of the
302 of both hands; 8 of one hand's 151 for the per-hand lamps). Every expected value is worked out by hand."""
from __future__ import annotations

import numpy as np
import pytest

from touchanything.core.tactile_layout import TactileLayout
from touchanything.inference.evaluation.metrics import compute_tactile_metrics, contact_frames
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.frame_facts import hand_contact

LAYOUT = TactileLayout.default()
BEND = LAYOUT.bend
TACTILE = LAYOUT.valid & ~LAYOUT.bend
CELLS = [np.nonzero(TACTILE[h]) for h in range(2)]
"""Per hand, the (rows, cols) of its tactile cells in a fixed order."""


def zeros() -> np.ndarray:
    return np.where(LAYOUT.valid, 0.0, np.nan)


def pressed(counts: tuple[int, int], value: float, start: int = 0) -> np.ndarray:
    """(2, 21, 21): 0 on the layout, `value` on tactile cells start … start + n − 1 of each hand."""
    grid = zeros()
    for h, n in enumerate(counts):
        rows, cols = CELLS[h]
        grid[h, rows[start:start + n], cols[start:start + n]] = value
    return grid


def test_the_layout_counts_the_rule_depends_on():
    assert TACTILE.sum() == 302 and TACTILE.sum(axis=(1, 2)).tolist() == [151, 151]  # 5 %: 15.1 → 16; 7.55 → 8


def test_contact_iou_counts_cells_strictly_above_one_tenth():
    """Left hand, cells a (4) b (3) c (2) d (5) in layout order:
         measured  a 0.15, b 0.1,    c 0.1001, d 0.0999 → in contact: a, c (6 cells)
         predicted a 0.15, b 0.1001, c 0.1,    d 0.0999 → in contact: a, b (7 cells)
    intersection a = 4, union a ∪ b ∪ c = 9: C-IoU 4/9 (with ≥ 0.1 it would be 9/9, with 0.2 NaN)."""
    rows, cols = CELLS[0]
    spans = {"a": slice(0, 4), "b": slice(4, 7), "c": slice(7, 9), "d": slice(9, 14)}
    measured, predicted = zeros(), zeros()
    for name, m, p in (("a", 0.15, 0.15), ("b", 0.1, 0.1001), ("c", 0.1001, 0.1), ("d", 0.0999, 0.0999)):
        measured[0, rows[spans[name]], cols[spans[name]]] = m
        predicted[0, rows[spans[name]], cols[spans[name]]] = p
    for dtype in (np.float64, np.float32):  # float32 0.1 (the engine's maps) is not above 0.1 either
        metrics = compute_tactile_metrics(predicted[None].astype(dtype), measured[None].astype(dtype), BEND)
        assert metrics["contact_iou"] == pytest.approx(4 / 9, abs=1e-12), dtype
    running = RunningMetrics(BEND)  # the replay's and the dashboard's running figures: the same rule by default
    running.add(predicted.astype(np.float32), measured)
    assert running.cumulative()["contact_iou"] == pytest.approx(4 / 9, abs=1e-12)


FRAMES = [  # (measured frame, its contact flag by hand)
    (pressed((8, 8), 0.15), True),    # 16 of 302 above 0.1
    (pressed((8, 7), 0.15), False),   # 15 of 302
    (pressed((8, 8), 0.1), False),    # 16 at exactly 0.1: not above
    (pressed((8, 8), 0.1001), True),  # 16 just above
    (pressed((8, 8), 0.0999), False),  # 16 just below
    (np.where(BEND, 0.5, pressed((8, 7), 0.5)), False),  # 15 tactile + every bend cell: bend cells do not count
]


def test_the_frame_contact_flag_needs_16_of_302_cells_strictly_above_one_tenth():
    grids = np.stack([frame for frame, _ in FRAMES])
    assert contact_frames(grids, BEND).tolist() == [flag for _, flag in FRAMES]
    # through the metrics (their own flag code): measured flags T F F T F F, predicted none in contact
    metrics = compute_tactile_metrics(np.stack([zeros()] * len(FRAMES)), grids, BEND)
    assert metrics["temporal_accuracy"] == pytest.approx(4 / 6, abs=1e-12)  # agree on the four "no contact" frames
    assert metrics["temporal_support"] == 2  # measured contact frames: 0 and 3
    assert (metrics["num_gt_onsets"], metrics["num_gt_offsets"]) == (1, 2)  # on at 3; off at 1 and 4
    # the prediction in contact on every frame: precision 2/6, recall 1
    metrics = compute_tactile_metrics(np.stack([pressed((8, 8), 0.5)] * len(FRAMES)), grids, BEND)
    assert metrics["temporal_precision"] == pytest.approx(2 / 6, abs=1e-12) and metrics["temporal_recall"] == 1.0
    assert metrics["temporal_accuracy"] == pytest.approx(2 / 6, abs=1e-12)


def test_five_percent_exactly_is_contact():
    """Only 20 (then 21) measured tactile cells, NaN elsewhere: 1 of 20 above 0.1 is 5 % (contact), 1 of 21 is not."""
    frames = []
    for cells in (20, 21):
        frame = np.full((2, 21, 21), np.nan)
        rows, cols = CELLS[0]
        frame[0, rows[:cells], cols[:cells]] = 0.0
        frame[0, rows[0], cols[0]] = 0.5
        frames.append(frame)
    grids = np.stack(frames)
    assert contact_frames(grids, BEND).tolist() == [True, False]
    for frame, flag in zip(grids, (True, False)):
        assert compute_tactile_metrics(frame[None], frame[None], BEND)["temporal_support"] == int(flag)


@pytest.mark.parametrize("count, value, contact", [
    (8, 0.15, True), (7, 0.15, False), (8, 0.1, False), (8, 0.1001, True), (8, 0.0999, False), (151, 0.1, False),
    (0, 0.0, False)])
def test_the_lamp_rule_per_hand_is_8_of_151_cells_strictly_above_one_tenth(count, value, contact):
    for dtype in (np.float64, np.float32):
        grid = pressed((count, 0), value).astype(dtype)  # the left hand pressed, the right not
        assert hand_contact(grid, BEND).tolist() == [contact, False], dtype
        assert hand_contact(pressed((0, count), value).astype(dtype), BEND).tolist() == [False, contact], dtype
