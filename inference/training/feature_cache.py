"""Per-frame backbone tokens of a frozen backbone, kept in memory (fp16) so later epochs skip it."""
from __future__ import annotations

import torch

from touchanything.inference.model.vision_encoder import VisionEncoder


class FeatureCache:
    """Keyed by (episode index, view, frame index); values (N, D) float16 on the CPU."""

    def __init__(self) -> None:
        self._store: dict[tuple[int, str, int], torch.Tensor] = {}
        self.hits = self.misses = 0

    def __len__(self) -> int:
        return len(self._store)

    def tokens(self, encoder: VisionEncoder, views: dict[str, torch.Tensor], episodes: torch.Tensor,
               frames: torch.Tensor, device: torch.device) -> dict[str, torch.Tensor]:
        """views {name: (B, T, 3, H, W)}, episodes (B,), frames (B, T) → {name: (B, T, N, D) float32}."""
        out = {}
        for view, images in views.items():
            keys = [(int(e), view, int(f)) for e, row in zip(episodes, frames) for f in row]
            if all(k in self._store for k in keys):
                self.hits += 1
                stacked = torch.stack([self._store[k] for k in keys])
                out[view] = stacked.reshape(*frames.shape, *stacked.shape[1:]).to(device, torch.float32)
                continue
            self.misses += 1
            with torch.no_grad():
                encoded = encoder(images.to(device))
            for key, value in zip(keys, encoded.reshape(-1, *encoded.shape[2:]).to("cpu", torch.float16)):
                self._store[key] = value
            out[view] = encoded.float()
        return out
