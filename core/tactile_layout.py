"""Tactile layout: where each of a glove's 256 raw slots lands on the 21×21 display grid.

Grids are in display coordinates: a palm view with fingers up. The left grid comes straight from the left
mapping file; the right grid is the right mapping mirrored left–right (`grid_R[r, c]` from key `r,20-c`),
as in the official data. Cells outside the layout are NaN.
"""
from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from touchanything.core.errors import DataError
from touchanything.core.json_files import read_json_file
from touchanything.core.snapshot import HANDS

GRID_SIZE = 21
RAW_SLOTS = 256
MAPPING_FILES = ("pressure_position_mapping_left.json", "pressure_position_mapping_right.json")
BEND_FILE = "hand_joint_positions.json"


def _parse_cell(path: Path, key: str) -> tuple[int, int]:
    parts = key.split(",")
    try:
        row, col = int(parts[0]), int(parts[1])
    except (ValueError, IndexError):
        raise DataError(path, f'key "{key}"', 'expected "row,col"') from None
    if len(parts) != 2 or not (0 <= row < GRID_SIZE and 0 <= col < GRID_SIZE):
        raise DataError(path, f'key "{key}"', f"cell outside the {GRID_SIZE}×{GRID_SIZE} grid")
    return row, col


def read_mapping(path: Path) -> np.ndarray:
    """Read an official `{"row,col": sensor_index}` file into a (21, 21) int16 grid, −1 where unmapped."""
    data = read_json_file(path)
    if not isinstance(data, dict) or not data:
        raise DataError(path, None, 'expected a non-empty object {"row,col": sensor_index}')
    grid = np.full((GRID_SIZE, GRID_SIZE), -1, np.int16)
    for key, value in data.items():
        row, col = _parse_cell(path, key)
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < RAW_SLOTS:
            raise DataError(path, f'key "{key}"', f"sensor index must be an integer 0–{RAW_SLOTS - 1}")
        grid[row, col] = value
    return grid


def read_bend_cells(path: Path) -> np.ndarray:
    """Read the official `hand_joint_positions.json` into (2, 21, 21) bool (display coordinates)."""
    data = read_json_file(path)
    bend = np.zeros((2, GRID_SIZE, GRID_SIZE), bool)
    if not isinstance(data, dict):
        raise DataError(path, None, "expected an object with 'left' and 'right' lists")
    for h, hand in enumerate(HANDS):
        cells = data.get(hand)
        if not isinstance(cells, list):
            raise DataError(path, hand, "missing or not a list of cells")
        for i, cell in enumerate(cells):
            try:
                row, col = int(cell["row"]), int(cell["col"])
            except (TypeError, KeyError, ValueError):
                raise DataError(path, f"{hand}[{i}]", "expected integer 'row' and 'col'") from None
            if not (0 <= row < GRID_SIZE and 0 <= col < GRID_SIZE):
                raise DataError(path, f"{hand}[{i}]", f"cell {row},{col} outside the grid")
            bend[h, row, col] = True
    return bend


@dataclass(frozen=True)
class TactileLayout:
    """sensor_index: (2, 21, 21) int16 raw slot per display cell, −1 outside; bend: (2, 21, 21) bool."""

    sensor_index: np.ndarray
    bend: np.ndarray
    source: str

    @classmethod
    def load(cls, mapping_left: Path, mapping_right: Path, bend_cells: Path) -> TactileLayout:
        """Load the three official-format files; bend cells must lie inside the layout."""
        left = read_mapping(Path(mapping_left))
        right = np.fliplr(read_mapping(Path(mapping_right)))
        index = np.stack([left, right])
        bend = read_bend_cells(Path(bend_cells))
        outside = bend & (index < 0)
        if outside.any():
            h, r, c = np.argwhere(outside)[0]
            raise DataError(bend_cells, HANDS[h], f"bend cell {r},{c} is outside the layout")
        return cls(index, bend, str(Path(mapping_left).parent))

    @classmethod
    def from_dir(cls, folder: Path) -> TactileLayout:
        """Load a folder holding the two mapping files and `hand_joint_positions.json`."""
        folder = Path(folder)
        return cls.load(folder / MAPPING_FILES[0], folder / MAPPING_FILES[1], folder / BEND_FILE)

    @classmethod
    def default(cls) -> TactileLayout:
        """The project's own layout (same geometry as the official one: 217 cells, 151 tactile + 66 bend)."""
        folder = resources.files("touchanything.core") / "layouts" / "default"
        with resources.as_file(folder) as path:
            return cls.from_dir(path)

    @property
    def valid(self) -> np.ndarray:
        """(2, 21, 21) bool: cells that carry a sensor."""
        return self.sensor_index >= 0

    @property
    def tactile(self) -> np.ndarray:
        """(2, 21, 21) bool: valid cells that are not bend cells (151 per hand in the official layout)."""
        return self.valid & ~self.bend

    def nan_mask(self) -> np.ndarray:
        """(2, 21, 21) float32: 0 inside the layout, NaN outside (add it to a grid to apply the mask)."""
        return np.where(self.valid, 0.0, np.nan).astype(np.float32)

    def used_sensors(self, hand: int) -> np.ndarray:
        """Sorted distinct raw slots used by one hand."""
        idx = self.sensor_index[hand]
        return np.unique(idx[idx >= 0])

    def hand_grid(self, raw: np.ndarray, hand: int) -> np.ndarray:
        """(..., 256) one hand's raw values → (..., 21, 21) float32 grid, NaN outside the layout."""
        valid = self.valid[hand]
        out = np.asarray(raw, dtype=np.float32)[..., np.where(valid, self.sensor_index[hand], 0)]
        out[..., ~valid] = np.nan
        return out

    def grid_from_raw(self, raw: np.ndarray) -> np.ndarray:
        """(..., 2, 256) raw values → (..., 2, 21, 21) float32 grid, NaN outside the layout."""
        raw = np.asarray(raw)
        return np.stack([self.hand_grid(raw[..., h, :], h) for h in range(2)], axis=-3)

    def raw_from_grid(self, grid: np.ndarray) -> np.ndarray:
        """(..., 2, 21, 21) cell values → (..., 2, 256) float32; a slot shared by cells gets their mean.

        Slots the layout does not use are 0. NaN cells outside the layout are ignored.
        """
        grid = np.asarray(grid, dtype=np.float32)
        lead = grid.shape[:-3]
        out = np.zeros(lead + (2, RAW_SLOTS), np.float32)
        for h in range(2):
            cells = self.valid[h]
            slots = self.sensor_index[h][cells]
            counts = np.bincount(slots, minlength=RAW_SLOTS).astype(np.float32)
            values = grid[..., h, :, :][..., cells].reshape(-1, slots.size)
            sums = np.stack([np.bincount(slots, weights=row, minlength=RAW_SLOTS) for row in values])
            used = counts > 0
            per_slot = np.zeros_like(sums, dtype=np.float32)
            per_slot[:, used] = sums[:, used] / counts[used]
            out[..., h, :] = per_slot.reshape(lead + (RAW_SLOTS,))
        return out
