"""Pressure panels: 21×21 hand maps on one fixed colour scale (never rescaled per frame), NaN cells as
background, nearest-neighbour upscaling, titles and a colour bar — as pure numpy/OpenCV images. A hand
with no value at all (a hand the model did not predict, see `unposed_as_nan`) is drawn as background
with a label saying why, never as a map that would read as zero pressure.

Bend cells (the gloves' finger flex sensors, `TactileLayout.bend`: 66 of a hand's 217 cells) measure how far a
finger is bent, not pressure: given a `bend` mask, a pressure map draws them hatched on their own grey scale
(`BEND_DARK` at 0 → `BEND_LIGHT` at 1), and an error map keeps its colours there but hatches them; a contact
outline never includes them (contact is decided on the tactile cells). A spread map is drawn without a mask: the
members' disagreement is one quantity on every cell."""
from __future__ import annotations

import functools

import cv2
import numpy as np

from touchanything.core.tactile_layout import TactileLayout
from touchanything.viz.colormap import ERROR_LUT, PRESSURE_LUT, apply, lookup_table

BACKGROUND = (26, 26, 46)
"""The official figure background #1a1a2e."""
AXES = (17, 17, 34)
FONT = cv2.FONT_HERSHEY_SIMPLEX
MAP_TITLES = {"measured": "measured pressure", "predicted": "predicted pressure", "error": "prediction − measured"}
"""What every user-facing text calls the three maps (the dashboard, the comparison video, Rerun)."""
SPREAD_TITLE = "members' spread"
"""What they call an ensemble's spread map (`Prediction.spread`)."""
SPREAD_HIGH = 0.5
"""The spread map's fixed scale is [0, SPREAD_HIGH]: the largest standard deviation values in [0, 1] can have."""
HAND_LABELS = ("left hand", "right hand")
"""The maps' hand labels, [left, right]."""
BEND_DARK, BEND_LIGHT = (70, 70, 78), (215, 215, 222)
"""A bend cell's grey at no flex (0) and at full flex (1): no colour of the pressure scale."""
BEND_LUT = lookup_table(((0.0, BEND_DARK), (1.0, BEND_LIGHT)))
HATCH = (20, 20, 24)
"""The hatch drawn over every bend cell (one pixel in HATCH_PERIOD along the diagonals)."""
HATCH_PERIOD = 3
BEND_NOTE = "hatched grey: finger bend (flex) sensors, not pressure"
"""What the hatched cells are, said beside the maps."""
UNUSED_BRIGHTNESS = 0.35
"""How bright a camera frame the model does not use is drawn (`dimmed`)."""


@functools.lru_cache(maxsize=1)
def layout_bend() -> np.ndarray:
    """(2, 21, 21) bool: the glove layout's bend cells (`TactileLayout.default().bend`; read-only)."""
    bend = TactileLayout.default().bend.copy()
    bend.flags.writeable = False
    return bend


def hand_map(grid: np.ndarray, cell: int, error: bool = False, high: float = 1.0,
             bend: np.ndarray | None = None) -> np.ndarray:
    """(21, 21) grid → (21·cell, 21·cell, 3) uint8; pressure on [0, high] or error on [−1, 1]. `bend` (21, 21)
    bool: those cells hatched, on the bend scale [0, 1] in a pressure map (see the module)."""
    colours = apply(grid, ERROR_LUT, -1.0, 1.0, AXES) if error else apply(grid, PRESSURE_LUT, 0.0, high, AXES)
    if bend is not None and not error:
        colours[bend] = apply(grid, BEND_LUT, 0.0, 1.0, AXES)[bend]
    image = cv2.resize(colours, (21 * cell, 21 * cell), interpolation=cv2.INTER_NEAREST)
    if bend is not None:
        _hatch(image, bend & np.isfinite(grid), cell)
    return image


def _hatch(image: np.ndarray, cells: np.ndarray, cell: int) -> None:
    """Draw HATCH diagonals over `cells` (21, 21) bool of an upscaled (21·cell)² hand map, in place."""
    image[_hatch_mask(np.ascontiguousarray(cells, bool).tobytes(), cell)] = HATCH


@functools.lru_cache(maxsize=16)
def _hatch_mask(cells: bytes, cell: int) -> np.ndarray:
    """(21·cell, 21·cell) bool: the HATCH diagonals (one pixel in HATCH_PERIOD) over the cells of a (21, 21) bool
    mask given as bytes (cached: a map's bend cells are the same frame after frame; read-only)."""
    grid = np.frombuffer(cells, bool).reshape(21, 21)
    rows, columns = np.indices((21 * cell, 21 * cell))
    mask = ((rows + columns) % HATCH_PERIOD == 0) & np.repeat(np.repeat(grid, cell, axis=0), cell, axis=1)
    mask.flags.writeable = False
    return mask


def draw_contact_outline(image: np.ndarray, grid: np.ndarray, cell: int, threshold: float,
                         colour: tuple[int, int, int] = (255, 255, 255)) -> None:
    """Outline, in place on an upscaled (21·cell)² hand map, the cells of `grid` (21, 21) strictly above
    `threshold` (NaN cells are outside), along cell borders."""
    region = np.nan_to_num(np.asarray(grid, np.float64), nan=0.0) > threshold
    if not region.any():
        return
    mask = np.repeat(np.repeat(region.astype(np.uint8), cell, axis=0), cell, axis=1)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    cv2.drawContours(image, contours, -1, (0, 0, 0), 3)
    cv2.drawContours(image, contours, -1, colour, 1)


def put_text(image: np.ndarray, text: str, origin: tuple[int, int], scale: float = 0.5,
             colour: tuple[int, int, int] = (255, 255, 255)) -> None:
    """Text with a black shadow one pixel down and right (readable on any background). Both are drawn with
    the same thickness: OpenCV's glyph advance grows with the thickness, so a thicker "outline" would run
    ahead of the text and show a stray letter at its end."""
    x, y = origin
    cv2.putText(image, text, (x + 1, y + 1), FONT, scale, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(image, text, origin, FONT, scale, colour, 1, cv2.LINE_AA)


def dimmed(image: np.ndarray) -> np.ndarray:
    """A camera frame the model does not use, as every panel draws it: a copy at UNUSED_BRIGHTNESS."""
    return (image * UNUSED_BRIGHTNESS).astype(np.uint8)


@functools.lru_cache(maxsize=16)
def colour_bar(height: int, width: int = 14, error: bool = False) -> np.ndarray:
    """A vertical colour bar, maximum at the top (cached: read-only)."""
    values = np.linspace(1.0, -1.0 if error else 0.0, height)[:, None].repeat(width, axis=1)
    bar = apply(values, ERROR_LUT if error else PRESSURE_LUT, -1.0 if error else 0.0, 1.0, AXES)
    bar.flags.writeable = False
    return bar


def unposed_as_nan(pressure: np.ndarray, hands_predicted: tuple[bool, bool]) -> np.ndarray:
    """A prediction's (2, 21, 21) pressure for display: a hand that was not predicted (no pose; the engine
    holds 0 there, "no contact" for the metrics) becomes all NaN, so that the maps label it instead."""
    if all(hands_predicted):
        return pressure
    shown = np.array(pressure, np.float32)
    shown[~np.asarray(hands_predicted, bool)] = np.nan
    return shown


def pressure_panel(grids: np.ndarray, title: str, width: int, height: int, error: bool = False,
                   outline: np.ndarray | None = None, threshold: float = 0.1, empty: str = "n/a",
                   high: float = 1.0, bend: np.ndarray | None = None) -> np.ndarray:
    """(2, 21, 21) → (height, width, 3) panel: title, both hands side by side, a colour bar. `outline`
    (2, 21, 21), e.g. the measured pressure, draws its contact region (> threshold) as a contour; a hand
    without any value reads `empty`; `high`: the top of the (non-error) scale (SPREAD_HIGH for a spread);
    `bend` (2, 21, 21) bool: those cells drawn as bend cells (see the module), BEND_NOTE under the maps."""
    panel = _panel_frame(title, width, height, error, high, bend is not None).copy()
    cell, top = panel_cell(width, height), 40
    maps = pressure_maps(grids, cell, error, outline, threshold, bar=False, empty=empty, high=high, bend=bend)
    panel[top:top + maps.shape[0], MAP_GAP:MAP_GAP + maps.shape[1]] = maps
    return panel


MAP_GAP, BAR_WIDTH = 10, 14


def panel_cell(width: int, height: int) -> int:
    """The cell size (pixels) that fits both hands and the bar in a (height, width) panel."""
    return max(1, min((width - 60) // 2 // 21, (height - 60) // 21))


def maps_width(cell: int) -> int:
    """Width of `pressure_maps(..., bar=True)`: two hands, the gaps and the colour bar."""
    return 2 * 21 * cell + 2 * MAP_GAP + BAR_WIDTH


def pressure_maps(grids: np.ndarray, cell: int, error: bool = False, outline: np.ndarray | None = None,
                  threshold: float = 0.1, bar: bool = True, empty: str = "n/a", high: float = 1.0,
                  bend: np.ndarray | None = None) -> np.ndarray:
    """(2, 21, 21) → (21·cell, maps_width(cell), 3): both hand maps (optionally with the contact outline
    of `outline`, its tactile cells only) and, with `bar`, the colour bar; without titles (for the dashboard's
    textures). A hand whose cells are all NaN is background with `empty` written on it (e.g. "no pose"); `high`:
    the top of the (non-error) scale; `bend` (2, 21, 21) bool: those cells drawn as bend cells (see the module)."""
    size = 21 * cell
    image = np.empty((size, maps_width(cell) if bar else 2 * size + MAP_GAP, 3), np.uint8)
    image[:, size:size + MAP_GAP] = BACKGROUND
    image[:, 2 * size + MAP_GAP:] = BACKGROUND
    for h in range(2):
        left = h * (size + MAP_GAP)
        if np.isnan(grids[h]).all():
            image[:, left:left + size] = BACKGROUND
            put_text(image, empty, (left + size // 2 - 4 * len(empty), size // 2), 0.45)
            continue
        image[:, left:left + size] = hand_map(grids[h], cell, error, high, None if bend is None else bend[h])
        if outline is not None:
            region = outline[h] if bend is None else np.where(bend[h], np.nan, outline[h])
            draw_contact_outline(image[:, left:left + size], region, cell, threshold)
    if bar:
        image[:, -BAR_WIDTH:] = colour_bar(size, error=error)
    return image


@functools.lru_cache(maxsize=64)
def _panel_frame(title: str, width: int, height: int, error: bool, high: float, bend_note: bool) -> np.ndarray:
    """Everything but the maps (drawn once per title and size: text rendering is the slow part); `bend_note`:
    BEND_NOTE under the hand labels."""
    panel = np.empty((height, width, 3), np.uint8)
    panel[:] = BACKGROUND
    put_text(panel, title, (10, 22), 0.6)
    top, size = 40, 21 * panel_cell(width, height)
    for h in range(2):
        put_text(panel, HAND_LABELS[h], (MAP_GAP + h * (size + MAP_GAP), top + size + 16), 0.45)
    if bend_note:
        put_text(panel, BEND_NOTE, (MAP_GAP, top + size + 34), 0.4, BEND_LIGHT)
    bar_left = MAP_GAP + 2 * (size + MAP_GAP)
    if bar_left + BAR_WIDTH <= width:
        panel[top:top + size, bar_left:bar_left + BAR_WIDTH] = colour_bar(size, error=error)
        put_text(panel, "+1" if error else f"{high:g}", (bar_left, top - 4), 0.35)
        put_text(panel, "-1" if error else "0", (bar_left, top + size + 12), 0.35)
    panel.flags.writeable = False
    return panel
