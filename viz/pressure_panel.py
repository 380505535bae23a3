"""Pressure panels: 21×21 hand maps on one fixed colour scale (never rescaled per frame), NaN cells as
background, nearest-neighbour upscaling, titles and a colour bar — as pure numpy/OpenCV images. A hand
with no value at all (a hand the model did not predict, see `unposed_as_nan`) is drawn as background
with a label saying why, never as a map that would read as zero pressure."""
from __future__ import annotations

import functools

import cv2
import numpy as np

from touchanything.viz.colormap import ERROR_LUT, PRESSURE_LUT, apply

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
UNUSED_BRIGHTNESS = 0.35
"""How bright a camera frame the model does not use is drawn (`dimmed`)."""


def hand_map(grid: np.ndarray, cell: int, error: bool = False, high: float = 1.0) -> np.ndarray:
    """(21, 21) grid → (21·cell, 21·cell, 3) uint8; pressure on [0, high] or error on [−1, 1]."""
    colours = apply(grid, ERROR_LUT, -1.0, 1.0, AXES) if error else apply(grid, PRESSURE_LUT, 0.0, high, AXES)
    return cv2.resize(colours, (21 * cell, 21 * cell), interpolation=cv2.INTER_NEAREST)


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
                   high: float = 1.0) -> np.ndarray:
    """(2, 21, 21) → (height, width, 3) panel: title, both hands side by side, a colour bar. `outline`
    (2, 21, 21), e.g. the measured pressure, draws its contact region (> threshold) as a contour; a hand
    without any value reads `empty`; `high`: the top of the (non-error) scale (SPREAD_HIGH for a spread)."""
    panel = _panel_frame(title, width, height, error, high).copy()
    cell, top = panel_cell(width, height), 40
    maps = pressure_maps(grids, cell, error, outline, threshold, bar=False, empty=empty, high=high)
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
                  threshold: float = 0.1, bar: bool = True, empty: str = "n/a", high: float = 1.0) -> np.ndarray:
    """(2, 21, 21) → (21·cell, maps_width(cell), 3): both hand maps (optionally with the contact outline
    of `outline`) and, with `bar`, the colour bar; without titles (for the dashboard's textures). A hand
    whose cells are all NaN is background with `empty` written on it (e.g. "no pose"); `high`: the top of the
    (non-error) scale."""
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
        image[:, left:left + size] = hand_map(grids[h], cell, error, high)
        if outline is not None:
            draw_contact_outline(image[:, left:left + size], outline[h], cell, threshold)
    if bar:
        image[:, -BAR_WIDTH:] = colour_bar(size, error=error)
    return image


@functools.lru_cache(maxsize=64)
def _panel_frame(title: str, width: int, height: int, error: bool, high: float) -> np.ndarray:
    """Everything but the maps (drawn once per title and size: text rendering is the slow part)."""
    panel = np.empty((height, width, 3), np.uint8)
    panel[:] = BACKGROUND
    put_text(panel, title, (10, 22), 0.6)
    top, size = 40, 21 * panel_cell(width, height)
    for h in range(2):
        put_text(panel, HAND_LABELS[h], (MAP_GAP + h * (size + MAP_GAP), top + size + 16), 0.45)
    bar_left = MAP_GAP + 2 * (size + MAP_GAP)
    if bar_left + BAR_WIDTH <= width:
        panel[top:top + size, bar_left:bar_left + BAR_WIDTH] = colour_bar(size, error=error)
        put_text(panel, "+1" if error else f"{high:g}", (bar_left, top - 4), 0.35)
        put_text(panel, "-1" if error else "0", (bar_left, top + size + 12), 0.35)
    panel.flags.writeable = False
    return panel
