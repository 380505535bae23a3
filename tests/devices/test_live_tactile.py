"""Live measured pressure: the streaming pipeline equals the episode pipeline once the running maximum
has reached the episode maximum, and stays finite and in range at the extremes."""
from __future__ import annotations

import numpy as np

from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.rig.live_tactile import LiveTactile
from touchanything.devices.tactile_pipeline import TactileConfig, process_raw


def test_streaming_grids_equal_the_episode_grids_after_the_peak():
    layout = TactileLayout.default()
    rng = np.random.default_rng(0)
    raw = rng.integers(0, 12, (40, 2, 256)).astype(np.uint8)
    raw[5, :, :] = 250  # the episode maximum comes early
    config = TactileConfig(broken_columns=(("left", 3),))
    offline = process_raw(raw, layout, config).grids
    live = LiveTactile(layout, config)
    grids = np.stack([live.grid(r) for r in raw])
    np.testing.assert_allclose(grids[5:], offline[5:], atol=1e-6)
    assert np.array_equal(np.isnan(grids), np.isnan(offline))


def test_extremes_stay_finite_and_in_range():
    layout = TactileLayout.default()
    live = LiveTactile(layout)
    for raw in (np.zeros((2, 256), np.uint8), np.full((2, 256), 255, np.uint8), np.zeros((2, 256), np.uint8)):
        grid = live.grid(raw)
        inside = grid[layout.valid]
        assert np.isfinite(inside).all() and (inside >= 0).all() and (inside <= 1).all()
        assert np.isnan(grid[~layout.valid]).all()
    live.reset()
    assert np.nanmax(live.grid(np.full((2, 256), 255, np.uint8))) == 1.0


def test_live_grids_by_hand():
    """One tactile sensor slot s and one bend slot b of the left hand (their cells found in the layout), the right
    glove at 20 everywhere:
    - left baseline: frame 0 reads 5 on every sensor the layout uses (mean 5 < 15; the slots it does not use read 200
      and do not count), so 5 is subtracted from then on (clipped at 0);
    - right: the mean 20 ≥ 15, no baseline; 20 / max(running max 20, min_scale 60) = 1/3 on every cell;
    - left s: +30 (frame 1) → 30 / max(30, 60) = 0.5; +120 (frame 2) → 1.0; +60 (frame 3) → 60 / 120 = 0.5 (the
      running maximum holds); 3 raw (frame 4, below the baseline) → 0;
    - left b: +90 (frame 2) → 1.0 (bend cells have their own maximum); +45 (frame 3) → 0.5;
    - after `reset()`: the next sample is the new baseline, so it reads 0."""
    layout = TactileLayout.default()
    index = layout.sensor_index[0]
    s = next(int(i) for i in index[layout.tactile[0]] if not (layout.bend[0] & (index == i)).any())
    b = next(int(i) for i in index[layout.bend[0]] if not (layout.tactile[0] & (index == i)).any())
    raw = np.full((5, 2, 256), 5, np.uint8)
    raw[:, 1] = 20
    raw[:, 0, np.setdiff1d(np.arange(256), layout.used_sensors(0))] = 200
    raw[1, 0, s], raw[2, 0, s], raw[3, 0, s], raw[4, 0, s] = 35, 125, 65, 3
    raw[2, 0, b], raw[3, 0, b] = 95, 50
    expected_s, expected_b = (0.0, 0.5, 1.0, 0.5, 0.0), (0.0, 0.0, 1.0, 0.5, 0.0)
    live = LiveTactile(layout)
    for frame in range(5):
        grid = live.grid(raw[frame])
        want = np.where(layout.valid[0], 0.0, np.nan)
        want[index == s], want[index == b] = expected_s[frame], expected_b[frame]
        np.testing.assert_allclose(grid[0], want, atol=1e-6, err_msg=f"left, frame {frame}")
        np.testing.assert_allclose(grid[1], np.where(layout.valid[1], 1 / 3, np.nan), atol=1e-6, err_msg=f"right, frame {frame}")
    live.reset()
    assert np.nanmax(live.grid(raw[2])[0]) == 0.0  # the new baseline
