"""Every stride-1 clip of a trajectory through the model, each frame encoded once.

The official protocol runs the whole model on every clip start 0…T−15 (8 frames, interval 2), so each frame's
backbone runs up to 8 times. The backbone and the view fusion look at one frame only, so here each frame is
read, resized and encoded once, in batches, on the model's device; the clips' window halves (`model.head`:
temporal transformer, pose encoder, fusion, decoder) then run in batches over the cached frame features. The
outputs are the official ones (the same modules on the same inputs; float rounding aside). Frames are read
and encoded as the clips advance, so memory holds `batch_size + 14` frames' features, whatever T is.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from touchanything.core.errors import UserError
from touchanything.devices.episodes.episode import Episode
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN, TACTILE_SIZE
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import blank_frames, resize_frame, to_model_input
from touchanything.inference.model.torch_device import autocast
from touchanything.inference.model.touch_model import TouchAnything

GRID = (2, TACTILE_SIZE, TACTILE_SIZE)


@dataclass
class TrajectoryPrediction:
    """stitched, causal: (T, 2, 21, 21) float32, NaN where a frame has no prediction."""

    stitched: np.ndarray
    causal: np.ndarray


class FrameFeatures:
    """The per-frame half of the model over a trajectory, as a sliding buffer of (K, N, D) features.

    `upto(end)` encodes frames up to `end` (exclusive) that are not encoded yet; `drop_before(first)` frees
    older ones; `clips(starts)` gathers (B, 8, N, D) for clip starts."""

    def __init__(self, model: TactileModel, episode: Episode, views: tuple[str, ...], ego_path: str,
                 batch_size: int, precision: str, blank: bool = False) -> None:
        missing = next((v for v in views if v not in episode.views), None)
        if missing:
            raise UserError(f"{episode.path}: view {missing} is missing; evaluate with fewer views")
        self.model, self.episode, self.views, self.blank = model, episode, views, blank
        self.official_frames = views == ("ego",) and ego_path == "frames" and isinstance(model, TouchAnything)
        self.batch_size, self.precision = batch_size, precision
        self.device = next(model.parameters()).device
        self.first = self.end = 0
        self.buffer: torch.Tensor | None = None
        self._blank_features: torch.Tensor | None = None

    def _read(self, view: str, index: int) -> np.ndarray:
        image = self.episode.views[view].read(index)
        if image is None:
            raise UserError(f"{self.episode.path}: view {view} has no frame {index}")
        return resize_frame(image, self.model.config.image_size)

    def _encode(self, start: int, stop: int) -> torch.Tensor:
        """(stop − start, N, D) features of frames [start, stop), in float32. Blank: every frame's features are
        those of one black frame per view (the per-frame half sees one frame only), encoded once."""
        if not self.blank:
            return self._encode_frames({v: np.stack([self._read(v, i) for i in range(start, stop)]) for v in self.views})
        if self._blank_features is None:
            size = self.model.config.image_size
            self._blank_features = self._encode_frames({v: blank_frames((1, size, size, 3)) for v in self.views})
        return self._blank_features.expand(stop - start, -1, -1)

    def _encode_frames(self, frames: dict[str, np.ndarray]) -> torch.Tensor:
        """{view: (K, S, S, 3) uint8} → (K, N, D) float32 features."""
        inputs = {v: to_model_input(images)[None].to(self.device) for v, images in frames.items()}
        with autocast(self.device, self.precision):
            if self.official_frames:
                visual = self.model.vision_encoder(inputs["ego"])
            else:
                visual = self.model.encode_frames(inputs)
        return visual[0].float()

    def upto(self, end: int) -> int:
        """Encode frames [self.end, end); returns how many were encoded."""
        done = 0
        while self.end < end:
            stop = min(end, self.end + self.batch_size)
            new = self._encode(self.end, stop)
            self.buffer = new if self.buffer is None else torch.cat([self.buffer, new])
            done, self.end = done + stop - self.end, stop
        return done

    def drop_before(self, first: int) -> None:
        if first > self.first and self.buffer is not None:
            self.buffer = self.buffer[first - self.first:]
            self.first = first

    def clips(self, index: np.ndarray) -> torch.Tensor:
        """index (B, 8) frame indices → (B, 8, N, D)."""
        return self.buffer[torch.from_numpy(index - self.first).to(self.device)]


@torch.no_grad()
def predict_trajectory(model: TactileModel, episode: Episode, views: tuple[str, ...], batch_size: int = 16,
                       ego_path: str = "frames", precision: str = "fp32",
                       on_frames: Callable[[int], None] | None = None, blank: bool = False) -> TrajectoryPrediction:
    """Stitched (average of the clips covering a frame) and causal (last frame of the clip ending on it)
    predictions of every stride-1 clip, `batch_size` clips (and frames) per forward pass. `on_frames(n)` is
    told how many frames were just encoded (for a progress bar). A trajectory shorter than 15 frames or
    without a WiLoR pose has no prediction (all NaN). `blank`: the pose-only baseline, every frame of every
    view in `views` black (`blank_frames`; no frame is decoded)."""
    count = episode.num_frames
    causal = np.full((count, *GRID), np.nan, np.float32)
    if count < SPAN or episode.wilor is None:
        on_frames and on_frames(count)
        return TrajectoryPrediction(causal.copy(), causal)
    stitched_sum, covered = np.zeros((count, *GRID), np.float64), np.zeros(count, np.int64)
    poses = torch.from_numpy(prepare_poses(episode.wilor.joints.reshape(count, 42, 3), episode.wilor.valid))
    features = FrameFeatures(model, episode, views, ego_path, batch_size, precision, blank)
    offsets = np.arange(CLIP_LENGTH) * FRAME_INTERVAL
    starts = np.arange(count - SPAN + 1)
    for first in range(0, len(starts), batch_size):
        index = starts[first:first + batch_size, None] + offsets[None]
        encoded = features.upto(int(index.max()) + 1)
        on_frames and encoded and on_frames(encoded)
        with autocast(features.device, precision):
            out = model.head(features.clips(index), poses[index].to(features.device))
        out = out.float().cpu().numpy()
        features.drop_before(int(index[-1, 0]) + 1)  # the next batch's clips start after this one's
        np.add.at(stitched_sum, index.ravel(), out.reshape(-1, *GRID))
        np.add.at(covered, index.ravel(), 1)
        causal[index[:, -1]] = out[:, -1]
    stitched = np.full((count, *GRID), np.nan, np.float32)
    has = covered > 0
    stitched[has] = (stitched_sum[has] / covered[has, None, None, None]).astype(np.float32)
    return TrajectoryPrediction(stitched, causal)
