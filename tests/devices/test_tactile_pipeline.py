"""Raw → grid pipeline: baseline, column repair, separate normalisation, at the extremes."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.tactile_pipeline import TactileConfig, process_raw

LAYOUT = TactileLayout.default()


def check_range_and_nan(grids: np.ndarray) -> None:
    valid = np.broadcast_to(LAYOUT.valid, grids.shape)
    assert np.isnan(grids[~valid]).all()
    inside = grids[valid]
    assert np.isfinite(inside).all()
    assert inside.min() >= 0.0 and inside.max() <= 1.0


@settings(max_examples=60, deadline=None)
@given(arrays(np.uint8, st.tuples(st.integers(1, 6), st.just(2), st.just(256))))
def test_any_raw_input_gives_unit_range_with_layout_nans(raw):
    out = process_raw(raw, LAYOUT)
    check_range_and_nan(out.grids)
    assert np.all(out.tactile_max >= TactileConfig.min_scale) and np.all(np.isfinite(out.bend_max))


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 5), st.integers(0, 1), st.integers(0, 255), st.integers(0, 255))
def test_one_saturated_sensor(frames, hand, slot_choice, background):
    slot = int(LAYOUT.used_sensors(hand)[slot_choice % len(LAYOUT.used_sensors(hand))])
    raw = np.full((frames, 2, 256), background, np.uint8)
    raw[-1, hand, slot] = 255
    out = process_raw(raw, LAYOUT)
    check_range_and_nan(out.grids)
    cells = LAYOUT.sensor_index[hand] == slot
    if background < 255:
        assert np.all(out.grids[-1, hand][cells] == 1.0)


def test_all_zero_gives_zero_and_no_division_by_zero():
    out = process_raw(np.zeros((4, 2, 256), np.uint8), LAYOUT)
    check_range_and_nan(out.grids)
    assert np.all(out.grids[:, LAYOUT.valid] == 0.0)
    assert out.baseline_applied.all()


def test_all_255_is_full_scale_without_baseline():
    out = process_raw(np.full((3, 2, 256), 255, np.uint8), LAYOUT)
    assert not out.baseline_applied.any()
    assert np.all(out.grids[:, LAYOUT.valid] == 1.0)
    assert np.all(out.tactile_max == 255.0)


def test_baseline_rule_threshold_15():
    low = np.full((2, 2, 256), 14, np.uint8)
    low[1] = 100
    out = process_raw(low, LAYOUT)
    assert out.baseline_applied.all()
    assert np.all(out.grids[0, LAYOUT.valid] == 0.0)  # the first frame becomes the zero level
    high = np.full((2, 2, 256), 15, np.uint8)
    assert not process_raw(high, LAYOUT).baseline_applied.any()


def test_baseline_clips_below_zero():
    raw = np.full((2, 2, 256), 10, np.uint8)
    raw[1] = 3  # below the first frame
    out = process_raw(raw, LAYOUT)
    assert np.all(out.grids[:, LAYOUT.valid] == 0.0)


def test_tactile_and_bend_normalised_separately():
    raw = np.full((2, 2, 256), 0, np.uint8)
    for h in range(2):
        raw[1, h, LAYOUT.sensor_index[h][LAYOUT.tactile[h]]] = 200
        raw[1, h, LAYOUT.sensor_index[h][LAYOUT.bend[h]]] = 70
    out = process_raw(raw, LAYOUT)
    assert np.all(out.grids[1][LAYOUT.tactile] == 1.0) and np.all(out.grids[1][LAYOUT.bend] == 1.0)
    assert np.all(out.tactile_max == 200) and np.all(out.bend_max == 70)


def test_an_untouched_glove_never_reads_as_contact():
    """The simulator's gloves (bias, gain, noise) with zero pressure, through the default pipeline: no frame of
    any of 12 gloves meets the official contact rule (at the old divisor of 25 most frames did)."""
    from touchanything.devices.sim.touch import Glove
    from touchanything.inference.evaluation.metrics import contact_frames

    rates = {}
    for scale in (25.0, TactileConfig.min_scale):
        flags = []
        for seed in range(12):
            rng = np.random.default_rng(seed)
            glove = Glove.draw(rng, None)
            raw = np.stack([glove.raw(np.zeros((2, 21, 21)), LAYOUT, rng) for _ in range(150)])
            grids = process_raw(raw, LAYOUT, TactileConfig(min_scale=scale)).grids
            flags += [contact_frames(grids[:, h], LAYOUT.bend[h]) for h in range(2)]
        rates[scale] = float(np.mean(flags))
    assert rates[TactileConfig.min_scale] == 0.0 and rates[25.0] > 0.3


def test_min_scale_keeps_noise_small():
    raw = np.zeros((3, 2, 256), np.uint8)
    raw[1:] = 5
    out = process_raw(raw, LAYOUT, TactileConfig(min_scale=25.0))
    assert out.grids[1][LAYOUT.valid].max() == pytest.approx(5 / 25)


def test_broken_column_is_interpolated_from_neighbours():
    raw = np.zeros((2, 2, 256), np.uint8)
    right = 1
    column = 14  # display column of the right hand's palm
    for r in range(21):
        for c in range(21):
            if LAYOUT.valid[right, r, c]:
                raw[1, right, LAYOUT.sensor_index[right, r, c]] = 100 if c != column else 0
    repaired = process_raw(raw, LAYOUT, TactileConfig(broken_columns=(("right", column),)))
    plain = process_raw(raw, LAYOUT)
    rows = np.flatnonzero(LAYOUT.tactile[right, :, column])
    assert np.all(plain.grids[1, right, rows, column] == 0.0)
    assert np.all(repaired.grids[1, right, rows, column] == 1.0)


def test_wrong_raw_shape_is_rejected():
    with pytest.raises(ValueError, match=r"\(T, 2, 256\)"):
        process_raw(np.zeros((3, 256), np.uint8), LAYOUT)


def test_empty_episode():
    out = process_raw(np.zeros((0, 2, 256), np.uint8), LAYOUT)
    assert out.grids.shape == (0, 2, 21, 21)
