"""The pressure-map renderer shared by the dashboard and the exporter: nearest-neighbour cells on one fixed
colour scale, NaN and ±inf as background, saturation at the ends, the gaps and the colour bar."""
from __future__ import annotations

import numpy as np
import pytest

from touchanything.viz.colormap import ERROR_LUT, PRESSURE_LUT
from touchanything.viz.pressure_panel import (
    AXES,
    BACKGROUND,
    BAR_WIDTH,
    MAP_GAP,
    maps_width,
    pressure_maps,
    put_text,
    unposed_as_nan,
)

CELL = 7
SIZE = 21 * CELL


def cell_colour(image: np.ndarray, hand: int, row: int, column: int) -> np.ndarray:
    """The colour of one cell, checked to be uniform over its CELL × CELL block."""
    left = hand * (SIZE + MAP_GAP)
    block = image[row * CELL:(row + 1) * CELL, left + column * CELL:left + (column + 1) * CELL]
    assert (block == block[0, 0]).all(), "a cell is not one flat colour"
    return block[0, 0]


def test_cells_are_flat_blocks_on_a_fixed_scale():
    grids = np.zeros((2, 21, 21), np.float32)
    grids[0, 3, 4], grids[1, 20, 0], grids[1, 0, 20] = 1.0, 0.5, 7.0
    grids[0, 0, 0], grids[0, 1, 1], grids[0, 2, 2] = np.nan, np.inf, -np.inf
    image = pressure_maps(grids, CELL)
    assert image.shape == (SIZE, maps_width(CELL), 3) and image.dtype == np.uint8
    assert (cell_colour(image, 0, 5, 5) == PRESSURE_LUT[0]).all()
    assert (cell_colour(image, 0, 3, 4) == PRESSURE_LUT[255]).all()
    assert (cell_colour(image, 1, 20, 0) == PRESSURE_LUT[128]).all()
    assert (cell_colour(image, 1, 0, 20) == PRESSURE_LUT[255]).all()  # saturated, not rescaled
    for row in range(3):  # NaN and ±inf are background, not a colour of the scale
        assert (cell_colour(image, 0, row, row) == AXES).all()
    assert (image[:, SIZE:SIZE + MAP_GAP] == BACKGROUND).all()
    assert (image[:, 2 * SIZE + MAP_GAP:-BAR_WIDTH] == BACKGROUND).all()
    bar = image[:, -BAR_WIDTH:]
    assert (bar[0, 0] == PRESSURE_LUT[255]).all() and (bar[-1, 0] == PRESSURE_LUT[0]).all()


def test_the_scale_does_not_follow_the_frame():
    faint = np.full((2, 21, 21), 0.05, np.float32)
    assert (cell_colour(pressure_maps(faint, CELL), 0, 10, 10) == PRESSURE_LUT[13]).all()
    assert (pressure_maps(faint, CELL) == pressure_maps(faint.copy(), CELL)).all()


@pytest.mark.parametrize("value", [np.nan, 0.0, 1e9])
def test_empty_and_saturated_maps_render(value):
    grids = np.full((2, 21, 21), value, np.float32)
    for error in (False, True):
        image = pressure_maps(grids, 1, error=error, outline=grids, bar=False)
        assert image.shape == (21, 2 * 21 + MAP_GAP, 3)


def test_error_map_is_diverging_around_white():
    grids = np.zeros((2, 21, 21), np.float32)
    grids[0, 0, 0], grids[0, 0, 1] = -1.0, 1.0
    image = pressure_maps(grids, CELL, error=True)
    assert (cell_colour(image, 0, 0, 0) == ERROR_LUT[0]).all()
    assert (cell_colour(image, 0, 0, 1) == ERROR_LUT[255]).all()
    assert (cell_colour(image, 0, 5, 5) == ERROR_LUT[128]).all()


def test_the_outline_follows_the_contact_region():
    grids = np.zeros((2, 21, 21), np.float32)
    measured = np.zeros_like(grids)
    measured[1, 8:12, 8:12] = 0.5
    plain = pressure_maps(grids, CELL)
    outlined = pressure_maps(grids, CELL, outline=measured, threshold=0.1)
    changed = np.any(plain != outlined, axis=-1)
    assert not changed[:, :SIZE + MAP_GAP].any(), "the left hand has no contact to outline"
    rows, columns = np.nonzero(changed)
    left = SIZE + MAP_GAP
    assert rows.min() >= 8 * CELL - 2 and rows.max() <= 12 * CELL + 1
    assert columns.min() >= left + 8 * CELL - 2 and columns.max() <= left + 12 * CELL + 1
    assert (pressure_maps(grids, CELL, outline=measured, threshold=0.6) == plain).all()  # nothing above it


@pytest.mark.parametrize("text", ["measured pressure", "predicted pressure", "prediction − measured"])
def test_a_title_is_drawn_once_with_its_shadow_under_it(text):
    image = np.full((40, 400, 3), 128, np.uint8)
    put_text(image, text, (10, 25), 0.6)
    light = np.flatnonzero((image > 200).all(axis=2).any(axis=0))
    dark = np.flatnonzero((image < 60).all(axis=2).any(axis=0))
    assert light.size and dark.size
    assert light[-1] - 1 <= dark[-1] <= light[-1] + 2  # no stray glyph of a wider outline behind the text
    assert light[0] - 1 <= dark[0] <= light[0] + 2


def test_a_hand_without_a_pose_reads_no_pose_not_zero_pressure():
    """Bare-hand replay: a hand the engine did not predict (it holds 0 there) is drawn as background with its
    label, never as the blue of zero pressure; the predicted hand keeps its map."""
    from touchanything.core.tactile_layout import TactileLayout
    from touchanything.inference.engine.prediction import Prediction
    from touchanything.viz.dashboard.dashboard_panels import pressure_views
    from touchanything.viz.dashboard.dashboard_state import SessionState
    from touchanything.viz.frame_facts import frame_facts

    pressure = np.zeros((2, 21, 21), np.float32)
    prediction = Prediction(frame_index=0, t_us=0, pressure=pressure, hands_predicted=(True, False),
                            views_used=("ego",), latency_ms=1.0)
    truth = np.full((2, 21, 21), 0.3, np.float32)
    facts = frame_facts(pressure, prediction.hands_predicted, truth, TactileLayout.default().bend)
    views = pressure_views(SessionState(prediction=prediction, truth=truth, facts=facts), CELL, 0.1, False)
    for name in ("predicted", "error"):
        image, title = views[name]
        right = image[:, SIZE + MAP_GAP:2 * SIZE + MAP_GAP].astype(int)
        assert not (np.abs(right - PRESSURE_LUT[0]).max(axis=-1) < 20).any(), name
        assert (np.abs(right - BACKGROUND).max(axis=-1) < 8).mean() > 0.8 and (right > 200).all(axis=-1).sum() > 10, name
    assert (cell_colour(views["predicted"][0], 0, 5, 5) == PRESSURE_LUT[0]).all()
    assert views["predicted"][1] == "predicted pressure (no pose: right)"
    assert np.isnan(unposed_as_nan(pressure, (True, False))[1]).all() and (pressure == 0).all()  # a copy
