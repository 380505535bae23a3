"""The hand-pose estimator: an RGB frame in, the model's joints (42, 3) and validity (2,) out, in WiLoR's
camera frame, with each hand's confidence and the time it took.

MediaPipe's HandLandmarker (Tasks API, two hands) runs in VIDEO mode: it follows the hands of the previous
frame and re-detects palms only when it lost them, so results depend on the frames before. Frames must come
in order with increasing timestamps (ms): the replay uses the frames' own timestamps (deterministic: the
same video gives the same poses), the live rig the capture times. A timestamp that does not increase (a
seek back, a looping file) starts afresh, as does `reset()`. The landmarks become camera-frame joints
(`camera_frame`), then left / right hands with hysteresis and smoothing (`hand_tracks`).

MediaPipe's C++ side prints log lines to the process's stderr when a landmarker is made and on its first
frame; they are sent to /dev/null then (briefly, for the whole process).
"""
from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from touchanything.core.errors import UserError
from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.core.snapshot import POSE_FROM_CAMERA
from touchanything.devices.camera_pose.camera_frame import reprojection_px, to_camera_frame
from touchanything.devices.camera_pose.hand_tracks import HandDetection, HandTracks, TrackedHands
from touchanything.devices.camera_pose.model_file import read_model
from touchanything.devices.quiet_stderr import quiet_stderr

STAGE = "hand pose"
"""The estimator's stage name in per-stage times."""


@dataclass(frozen=True)
class CameraPoseConfig:
    """Settings of the hand pose estimated from the ego camera (a scene's `[hands]` with source = "camera").

    model: the hand-landmark .task file (None: the one built at install time). mirror: the image is mirrored
    (a selfie preview), so MediaPipe's labels are swapped. smoothing: weight of the previous joints in the
    exponential smoothing of a followed hand, in [0, 1) (0: none). handedness_frames: frames in a row a
    followed hand's label must say otherwise before the hand changes side (1: believe every frame)."""

    model: Path | None = None
    mirror: bool = False
    smoothing: float = 0.5
    handedness_frames: int = 5

    def __post_init__(self) -> None:
        if self.model is not None:
            object.__setattr__(self, "model", Path(self.model))
        if not (math.isfinite(self.smoothing) and 0 <= self.smoothing < 1):
            raise UserError(f"camera pose smoothing must lie in [0, 1) (0: none), got {self.smoothing}")
        if self.handedness_frames < 1:
            raise UserError(f"camera pose handedness_frames must be at least 1, got {self.handedness_frames}")


@dataclass(frozen=True)
class HandEstimate:
    """One frame's estimate: joints (42, 3) float32 (left 0–20, right 21–41, zeros where not found); valid
    (2,) bool; confidence (2,) float32; pixels (2, 21, 2) image landmarks (NaN where not found);
    reprojection_px (2,) mean landmark reprojection error of each found hand (NaN where not found);
    ms: time taken."""

    joints: np.ndarray
    valid: np.ndarray
    confidence: np.ndarray
    pixels: np.ndarray
    reprojection_px: np.ndarray
    ms: float

    def snapshot_fields(self) -> dict:
        """The Snapshot fields this estimate sets (`dataclasses.replace(snapshot, **fields)`)."""
        return {"joints": self.joints, "joints_valid": self.valid, "joints_confidence": self.confidence,
                "pose_source": POSE_FROM_CAMERA, "stage_ms": {STAGE: self.ms}}


def hands_found(valid: np.ndarray) -> str:
    """"both hands", "left hand only", "right hand only" or "no hand found" for (2,) validity."""
    left, right = bool(valid[0]), bool(valid[1])
    return {(True, True): "both hands", (True, False): "left hand only", (False, True): "right hand only",
            (False, False): "no hand found"}[(left, right)]


class HandPoseEstimator:
    """`estimate(image, timestamp_ms)` per frame, in order; `close()` (or `with`) releases MediaPipe. A
    missing or wrong model file is a UserError when the estimator is made."""

    def __init__(self, config: CameraPoseConfig = CameraPoseConfig()) -> None:
        self.config = config
        self._model = read_model(config.model)
        self.tracks = HandTracks(config.mirror, config.smoothing, config.handedness_frames)
        self._landmarker = None
        self._last_ms: int | None = None
        self._first = True
        self._open()

    def _open(self) -> None:
        from mediapipe.tasks.python import BaseOptions, vision

        options = vision.HandLandmarkerOptions(base_options=BaseOptions(model_asset_buffer=self._model),
                                               running_mode=vision.RunningMode.VIDEO, num_hands=2)
        with quiet_stderr():
            self._landmarker = vision.HandLandmarker.create_from_options(options)
        self._first = True

    def reset(self) -> None:
        """Forget the hands followed so far (the next frame is detected afresh)."""
        self.close()
        self.tracks.reset()
        self._last_ms = None
        self._open()

    def close(self) -> None:
        if self._landmarker is not None:
            self._landmarker.close()
            self._landmarker = None

    def __enter__(self) -> HandPoseEstimator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def estimate(self, image: np.ndarray, timestamp_ms: int) -> HandEstimate:
        """The hands in one (H, W, 3) uint8 RGB frame taken at `timestamp_ms`."""
        import mediapipe as mp

        start = time.perf_counter()
        timestamp_ms = int(timestamp_ms)
        if self._last_ms is not None and timestamp_ms <= self._last_ms:
            self.reset()
        self._last_ms = timestamp_ms
        height, width = image.shape[:2]
        frame = mp.Image(image_format=mp.ImageFormat.SRGB, data=np.ascontiguousarray(image, dtype=np.uint8))
        with quiet_stderr() if self._first else contextlib.nullcontext():
            result = self._landmarker.detect_for_video(frame, timestamp_ms)
        self._first = False
        detections = []
        for handedness, landmarks, world in zip(result.handedness, result.hand_landmarks, result.hand_world_landmarks):
            pixels = np.array([[p.x * width, p.y * height] for p in landmarks], np.float64)
            joints = to_camera_frame(np.array([[p.x, p.y, p.z] for p in world], np.float64), pixels, width, height)
            if joints is not None and handedness:
                detections.append(HandDetection(handedness[0].category_name, handedness[0].score, joints, pixels))
        return _estimate(self.tracks.update(detections, width, height), width, height, start)


def _estimate(hands: TrackedHands, width: int, height: int, start: float) -> HandEstimate:
    errors = np.array([reprojection_px(hands.joints[h], hands.pixels[h], width, height) if hands.valid[h] else np.nan
                       for h in range(2)], np.float32)
    return HandEstimate(hands.joints.reshape(2 * JOINTS_PER_HAND, 3), hands.valid, hands.confidence, hands.pixels,
                        errors, (time.perf_counter() - start) * 1000.0)
