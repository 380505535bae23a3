"""StreamingEngine: Snapshots in, Predictions out, with per-frame results cached for the last 15 frames.

Per frame: the views present (and allowed) are resized, normalised and encoded in one batched backbone
call, fused and cached with the frame's prepared pose. Then the window head runs for the output frame
only. For the newest frame the output equals the batch forward of the same 8-frame clip (interval 2).
See `touchanything.inference.engine.frame_ring` for drops, start and seek, and `EngineSetting` for the knobs.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.core.snapshot import HANDS, VIEW_NAMES, Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.inference.engine.engine_runtime import Runtime, make_runtime
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.frame_ring import CachedFrame, FrameRing, Window
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.stitching import StitchAccumulator
from touchanything.inference.model.model_config import CLIP_LENGTH
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.pose_encoder import prepare_poses, usable_hands
from touchanything.inference.model.preprocess import blank_frames

CENTRE = CLIP_LENGTH // 2


def _ms(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0


class StreamingEngine:
    """`step(snapshot) -> list[Prediction]` (newest: one per frame; centre/stitched: the frames that became
    ready, possibly none); `drain()` at the end of a stream returns what look-ahead held back (centre: the
    last 6 frames with newest-frame output; stitched: the partial averages of the last 14); `reset()` (or
    a frame index that does not increase) clears the cache."""

    def __init__(self, model: TactileModel, setting: EngineSetting = EngineSetting(), layout: TactileLayout | None = None,
                 clock: Callable[[], float] = time.monotonic, onnx_dir: Path | None = None,
                 threads: int | None = None) -> None:
        """`onnx_dir`: an ONNX setting's export folder (`touchanything export-onnx`; None: the user cache's
        export of `model`, made on first use); `threads`: CPU threads for the model (None: all cores but one)."""
        self.setting = setting
        self.image_size = model.config.image_size
        self.blank = model.config.blank_images or setting.blank  # a pose-only model or setting sees black frames
        self.runtime: Runtime = make_runtime(model, setting, onnx_dir, threads)
        self.mask = (layout or TactileLayout.default()).nan_mask()
        self.clock = clock
        self.ring = FrameRing()
        self.stitch = StitchAccumulator()
        self._emitted = -1
        self._count = 0
        self._last: Prediction | None = None

    def reset(self) -> None:
        self.ring.clear()
        self.stitch.clear()
        self._emitted, self._count, self._last = -1, 0, None

    def set_views(self, views: tuple[str, ...]) -> None:
        """Change the views the engine may use, mid-stream (cached frames keep the views they had)."""
        self.setting = dataclasses.replace(self.setting, views=tuple(views))

    def step(self, snapshot: Snapshot) -> list[Prediction]:
        start = time.perf_counter()
        if self.ring.is_seek(snapshot.frame_index):
            self.reset()
        views = tuple(v for v in VIEW_NAMES if v in self.setting.views and v in snapshot.images)
        if "ego" not in views:
            self.ring.note_index(snapshot.frame_index)
            return [self._without_prediction(snapshot, views, "no ego view: no prediction")]
        self._count += 1
        if (self._count - 1) % self.setting.every and self._last is not None:
            self.ring.note_index(snapshot.frame_index)
            return [self._held(snapshot)]
        timings = {}
        self.ring.add(self._encode(snapshot, views, timings))
        window = self.ring.window()
        outputs = {"newest": self._newest, "centre": self._centre, "stitched": self._stitched}[self.setting.output]
        predictions = outputs(window, timings)
        timings["total"] = _ms(start)
        return predictions

    def drain(self) -> list[Prediction]:
        """End of stream: the frames a look-ahead output still holds."""
        window = self.ring.window()
        if window is None or self.setting.output == "newest":
            return []
        if self.setting.output == "stitched":
            return [self._stitched_prediction(entry, {}) for entry in self.stitch.complete()]
        remaining = [i for i in self.ring.cached_indices() if i > self._emitted]
        return [p for i in remaining for p in self._newest(self.ring.window(end=i), {})]

    def _encode(self, snapshot: Snapshot, views: tuple[str, ...], timings: dict) -> CachedFrame:
        start = time.perf_counter()
        frames = [blank_frames((self.image_size, self.image_size, 3)) if self.blank else snapshot.images[v] for v in views]
        images = self.runtime.prepare(frames, self.image_size)
        view_ids = np.array([VIEW_NAMES.index(v) for v in views], np.int64)
        timings["preprocess"] = _ms(start)
        start = time.perf_counter()
        tokens = self.runtime.encode(images, view_ids)
        timings["encode"] = _ms(start)
        joints = np.asarray(snapshot.joints, np.float32).reshape(42, 3)
        valid = usable_hands(joints, np.asarray(snapshot.joints_valid, bool))
        return CachedFrame(snapshot.frame_index, tokens, prepare_poses(joints, valid), valid, views, snapshot.t_us)

    def _hand_sets(self, frames: list[CachedFrame]) -> list[tuple[int, ...]]:
        if self.setting.invalid_hands == "official":
            return [(0, 1)] * len(frames)
        return [tuple(h for h in (0, 1) if f.valid[h]) for f in frames]

    def _predict(self, window: Window, positions: list[int], timings: dict) -> tuple[np.ndarray, np.ndarray]:
        """Head outputs (P, 2, 21, 21) at window positions and which hands were predicted (P, 2); positions
        whose output frames differ in valid hands go through the head in separate calls."""
        frames = [window.frames[p] for p in positions]
        outputs = np.zeros((len(positions), 2, 21, 21), np.float32)
        hands = np.zeros((len(positions), 2), bool)
        sets = self._hand_sets(frames)
        tokens = [f.tokens for f in window.frames]
        for hand_set in sorted(set(sets)):
            rows = [i for i, s in enumerate(sets) if s == hand_set]
            if not hand_set:
                continue
            start = time.perf_counter()
            ids = np.concatenate([np.arange(JOINTS_PER_HAND) + JOINTS_PER_HAND * h for h in hand_set])
            joints = np.stack([frames[i].joints[ids] for i in rows])
            result = self.runtime.head(tokens, joints, ids, np.array([positions[i] for i in rows], np.int64))
            outputs[np.ix_(rows, hand_set)] = result
            hands[np.ix_(rows, hand_set)] = True
            timings["head"] = timings.get("head", 0.0) + _ms(start)
        return outputs, hands

    def _prediction(self, frame: CachedFrame, pressure: np.ndarray, hands: np.ndarray, timings: dict,
                    exact: bool) -> Prediction:
        missing = [HANDS[h] for h in (0, 1) if not hands[h]]
        status = "ok" if not missing else ("no valid hand pose" if len(missing) == 2 else f"{missing[0]} hand: no pose")
        prediction = Prediction(frame_index=frame.frame_index, t_us=frame.t_us, pressure=pressure + self.mask,
                                hands_predicted=(bool(hands[0]), bool(hands[1])), views_used=frame.views,
                                latency_ms=self._latency(frame.t_us), timings_ms=timings, status=status,
                                window_exact=exact)
        self._emitted = max(self._emitted, frame.frame_index)
        self._last = prediction
        return prediction

    def _emit(self, window: Window, positions: list[int], timings: dict) -> list[Prediction]:
        if not positions:
            return []
        outputs, hands = self._predict(window, positions, timings)
        return [self._prediction(window.frames[p], outputs[i], hands[i], timings, window.exact and not window.padded)
                for i, p in enumerate(positions)]

    def _newest(self, window: Window, timings: dict) -> list[Prediction]:
        return self._emit(window, [CLIP_LENGTH - 1], timings)

    def _centre(self, window: Window, timings: dict) -> list[Prediction]:
        fresh = window.frames[CENTRE].frame_index > self._emitted
        return self._emit(window, [CENTRE] if fresh else [], timings)

    def _stitched(self, window: Window, timings: dict) -> list[Prediction]:
        if not window.padded:
            outputs, hands = self._predict(window, list(range(CLIP_LENGTH)), timings)
            self.stitch.add(window.frames, outputs, hands, window.exact)
        return [self._stitched_prediction(entry, timings) for entry in self.stitch.complete(self.ring.newest)]

    def _stitched_prediction(self, entry, timings: dict) -> Prediction:
        return self._prediction(entry.frame, entry.mean(), entry.counts > 0, timings, entry.exact)

    def _latency(self, t_us: int) -> float:
        return (self.clock() * 1e6 - t_us) / 1000.0

    def _held(self, snapshot: Snapshot) -> Prediction:
        last = self._last
        return Prediction(frame_index=snapshot.frame_index, t_us=snapshot.t_us, pressure=last.pressure,
                          hands_predicted=last.hands_predicted, views_used=last.views_used,
                          latency_ms=self._latency(snapshot.t_us), status="held (prediction every k-th frame)",
                          window_exact=last.window_exact, held=True)

    def _without_prediction(self, snapshot: Snapshot, views: tuple[str, ...], reason: str) -> Prediction:
        return Prediction(frame_index=snapshot.frame_index, t_us=snapshot.t_us, pressure=None,
                          hands_predicted=(False, False), views_used=views, latency_ms=self._latency(snapshot.t_us),
                          status=reason, window_exact=False)
