"""dearpygui raw textures fed from uint8 RGB images through preallocated buffers (no allocation per
update): resize into a uint8 staging image, then scale into the float32 buffer the GPU texture reads."""
from __future__ import annotations

import cv2
import dearpygui.dearpygui as dpg
import numpy as np


class TextureSlot:
    """A (height, width) RGB texture registered in `registry`; `show(image)` takes any (H, W, 3) uint8."""

    def __init__(self, registry: int | str, width: int, height: int) -> None:
        self.width, self.height = width, height
        self._staging = np.zeros((height, width, 3), np.uint8)
        self._buffer = np.zeros(height * width * 3, np.float32)
        self.tag = dpg.add_raw_texture(width, height, self._buffer, format=dpg.mvFormat_Float_rgb, parent=registry)

    def show(self, image: np.ndarray) -> None:
        if image.shape[:2] == (self.height, self.width):
            self._staging[:] = image
        else:
            cv2.resize(image, (self.width, self.height), dst=self._staging, interpolation=cv2.INTER_AREA)
        np.multiply(self._staging.reshape(-1), np.float32(1 / 255), out=self._buffer, casting="unsafe")
        dpg.set_value(self.tag, self._buffer)

    @property
    def uploaded(self) -> np.ndarray:
        """(height, width, 3) uint8: the texture's content as last uploaded (a read-only copy; dearpygui gives no
        raw texture's value back)."""
        image = (self._buffer.reshape(self.height, self.width, 3) * 255).round().astype(np.uint8)
        image.flags.writeable = False
        return image
