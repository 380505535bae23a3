"""Live measured pressure: the streaming pipeline equals the episode pipeline once the running maximum
has reached the episode maximum, and stays finite and in range at the extremes."""
from __future__ import annotations

import numpy as np

from touchanything.devices.rig.live_tactile import LiveTactile
from touchanything.devices.tactile_layout import TactileLayout
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
