"""Bend cells (the gloves' finger flex sensors, 66 of a hand's 217 cells) are drawn as what they are:
hatched on their own grey scale in the dashboard's maps and the comparison video's panels, never on the pressure
scale, and never inside the measured contact outline."""
from __future__ import annotations

import numpy as np

from touchanything.core.tactile_layout import TactileLayout
from touchanything.viz.colormap import PRESSURE_LUT
from touchanything.viz.comparison_video import CAMERA_HEIGHT, PANEL_HEIGHT, WIDTH, comparison_frame
from touchanything.viz.pressure_panel import BEND_LUT, HATCH, MAP_GAP, layout_bend, panel_cell, pressure_maps

CELL = 7
SIZE = 21 * CELL
BEND = TactileLayout.default().bend


def _cell(image: np.ndarray, hand: int, row: int, column: int, cell: int = CELL, left: int = 0) -> np.ndarray:
    """The (cell, cell, 3) block of one cell."""
    x = left + hand * (21 * cell + MAP_GAP) + column * cell
    return image[row * cell:(row + 1) * cell, x:x + cell]


def _bent_hands() -> np.ndarray:
    """Both hands with their bend cells at full flex and every tactile cell at 0 (NaN outside the layout)."""
    layout = TactileLayout.default()
    grids = np.where(layout.valid, 0.0, np.nan).astype(np.float32)
    grids[BEND] = 1.0
    return grids


def test_the_layout_has_66_bend_cells_per_hand():
    assert layout_bend().sum(axis=(1, 2)).tolist() == [66, 66]


def test_a_bend_cell_is_hatched_grey_not_a_pressure_colour():
    grids = _bent_hands()
    image = pressure_maps(grids, CELL, bend=BEND)
    pressure = {tuple(c) for c in PRESSURE_LUT.tolist()}
    for hand in range(2):
        row, column = np.argwhere(BEND[hand])[0]
        colours = {tuple(c) for c in _cell(image, hand, row, column).reshape(-1, 3).tolist()}
        assert colours == {tuple(BEND_LUT[255].tolist()), HATCH}, colours  # full flex: the bend scale's top, hatched
        assert not colours & pressure
        tactile = np.argwhere(~BEND[hand] & np.isfinite(grids[hand]))[0]
        assert (_cell(image, hand, *tactile) == PRESSURE_LUT[0]).all()  # a tactile cell keeps the pressure scale


def test_the_measured_outline_leaves_bend_cells_out():
    """Pressure on bend cells alone is no contact (the lamps' rule): nothing to outline."""
    grids = np.zeros((2, 21, 21), np.float32)
    plain = pressure_maps(grids, CELL, bend=BEND)
    assert (pressure_maps(grids, CELL, outline=_bent_hands(), threshold=0.1, bend=BEND) == plain).all()


def test_the_comparison_video_draws_bend_cells_as_such():
    grids = _bent_hands()
    frame = comparison_frame({}, grids, grids, "footer")
    width = WIDTH // 3
    cell = panel_cell(width, PANEL_HEIGHT)
    measured = frame[CAMERA_HEIGHT + 40:CAMERA_HEIGHT + 40 + 21 * cell, :width]
    row, column = np.argwhere(BEND[0])[0]
    colours = {tuple(c) for c in _cell(measured, 0, row, column, cell, MAP_GAP).reshape(-1, 3).tolist()}
    assert colours == {tuple(BEND_LUT[255].tolist()), HATCH}, colours
