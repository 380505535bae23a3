"""Hand skeleton overlay: joint regions lie on pressure cells, projection follows the WiLoR camera."""
from __future__ import annotations

import numpy as np

from touchanything.app.sessions.bundled import sample_episodes
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.viz.hand_projection import draw_hands, project_wilor
from touchanything.viz.hand_regions import REGIONS, joint_pressure


def test_joint_regions_cover_only_pressure_cells_of_each_hand():
    layout = TactileLayout.default()
    for hand in range(2):
        union = REGIONS[hand].any(axis=0)
        assert not (union & ~layout.tactile[hand]).any()
        assert union.sum() > 100
    assert joint_pressure(np.full((2, 21, 21), np.nan)).shape == (2, 21)
    grids = np.where(layout.valid, 0.0, np.nan)
    grids[0, 2, 14] = 0.9  # left index fingertip pad
    values = joint_pressure(grids)
    assert values[0, 8] == np.float32(0.9) and np.nanmax(values[1]) == 0.0 and np.isnan(values[0, 6])


def test_projection_uses_the_wilor_focal_length_and_rejects_points_behind():
    uv = project_wilor(np.array([[0.0, 0.0, 50.0], [1.0, -1.0, 50.0], [0.0, 0.0, -1.0], [np.nan, 0, 1]]), 640, 480)
    focal = 5000 / 256 * 640
    assert np.allclose(uv[0], [320, 240]) and np.allclose(uv[1], [320 + focal / 50, 240 - focal / 50])
    assert np.isnan(uv[2:]).all()


def test_skeleton_is_drawn_where_the_hands_project_in_the_sample():
    with open_episode(sample_episodes()[0]) as episode:
        image = episode.views["ego"].read(100)
        joints, valid = episode.wilor.joints[100].reshape(42, 3), episode.wilor.valid[100]
        pressure = episode.pressure.grids[100]
    drawn = draw_hands(image, joints, valid, pressure)
    changed = np.any(drawn != image, axis=-1)
    assert valid.any() and changed.sum() > 200
    points = project_wilor(joints.reshape(2, 21, 3), image.shape[1], image.shape[0])
    hand = int(np.argmax(valid))
    u, v = np.nanmedian(points[hand], axis=0).astype(int)
    assert changed[max(v - 40, 0):v + 40, max(u - 40, 0):u + 40].any()
    assert np.array_equal(draw_hands(image, joints, np.zeros(2, bool), pressure), image)
