"""The measured pressure of a live glove stream, one sample at a time: the episode pipeline's steps
(baseline from the first sample, layout, broken-column repair, separate normalisation) with the episode
maximum replaced by the running maximum so far (never less than `min_scale`). Early frames of a session
can therefore read higher than the same frames converted offline once the whole episode is known."""
from __future__ import annotations

import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.tactile_pipeline import TactileConfig, repair_column


class LiveTactile:
    """`grid(raw)`: (2, 256) uint8 → (2, 21, 21) float32 in [0, 1], NaN outside the layout. `reset()`
    forgets the baseline and maxima (a new session or a replugged glove)."""

    def __init__(self, layout: TactileLayout, config: TactileConfig = TactileConfig()) -> None:
        self.layout, self.config = layout, config
        self.reset()

    def reset(self) -> None:
        self._baseline: list[np.ndarray | None] = [None, None]
        self._peak = np.zeros((2, 2))
        """Running maxima per hand: [tactile, bend]."""

    def grid(self, raw: np.ndarray) -> np.ndarray:
        raw = np.asarray(raw)
        if raw.shape != (2, 256):
            raise ValueError(f"raw pressure must have shape (2, 256), got {raw.shape}")
        out = np.empty((2, 21, 21), np.float32)
        for h, name in enumerate(HANDS):
            values = raw[h].astype(np.float32)
            if self._baseline[h] is None:
                sensors = self.layout.used_sensors(h)
                below = sensors.size and values[sensors].mean() < self.config.baseline_threshold
                self._baseline[h] = values.copy() if below else np.zeros_like(values)
            corrected = np.clip(values - self._baseline[h], 0.0, None)
            grid = self.layout.hand_grid(corrected[None], h)
            for hand_name, column in self.config.broken_columns:
                if hand_name == name:
                    repair_column(grid, self.layout, h, column)
            for k, cells in enumerate((self.layout.tactile[h], self.layout.bend[h])):
                values_k = grid[0, cells]
                if values_k.size:
                    self._peak[h, k] = max(self._peak[h, k], float(values_k.max()))
                scale = max(self._peak[h, k], self.config.min_scale)
                grid[0, cells] = np.clip(values_k / scale, 0.0, 1.0)
            out[h] = grid[0]
        return out
