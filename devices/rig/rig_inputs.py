"""How each live source's latest reading becomes part of a Snapshot: a table of rig inputs, one per source.

A `RigInput` names a source and says how its reading fills the Snapshot (`Fill`). At a tick every source's
latest reading is checked: a reading older than the staleness limit, or any reading of a source whose
device went away and is being retried (`retrying`), is refused (the paper's strategy keeps the latest
*valid* sample of every source) and the fill is given None, which records the absence; when the device
returns, its fresh readings are used again:

- `camera_fill(view)`: `images[view]` = the RGB image; without a fresh one the view is left out of `images`.
- `glove_fill(hand)`: the hand's row of `pressure_raw` and `imu_wxyz`, `glove_present[hand]` = True;
  without a fresh sample a zero row and False.
- `trackers_fill()`: `trackers` = the reading's poses by role; without a fresh reading, no trackers.
- `mocap_fill(to_model)`: `mocap_joints` / `mocap_valid` = the mocap hands, and `joints` / `joints_valid` =
  `to_model(mocap hands, present, trackers)`, the model's input; without a fresh reading zeros, invalid.
- `camera_hands_fill()`: the hands estimated from the ego camera (`CameraHandsReading`): `joints`,
  `joints_valid`, `joints_confidence`, the estimator's time in `stage_ms`, and `images["ego"]` = the very
  frame they were estimated in (so the picture and the skeleton agree); without a fresh reading the camera's
  newest frame stays and the hands are invalid.

The glove arrays exist as soon as the rig has a glove input, so a missing glove gives a zero row. Fills
run in the order given, except that fills reading the trackers (`mocap_fill`) run after all the others.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.core.snapshot import HANDS, POSE_FROM_CAMERA, POSE_FROM_MOCAP, VIEW_NAMES, Snapshot

MocapToModel = Callable[[np.ndarray, np.ndarray, dict[str, np.ndarray]], tuple[np.ndarray, np.ndarray]]
"""(mocap joints (2, 21, 3) float32, hands present (2,) bool, trackers {role: (7,)}) → (joints (2, 21, 3)
in the model's frame, valid (2,) bool); e.g. `touchanything.devices.rig.pose_transform.mocap_to_model_frame` with its
calibration bound."""


class LatestSource(Protocol):
    """What the rig clock needs of a source: `latest()` is an object with `t_us` (host monotonic µs) or
    None before the first sample; `status()` is its one-line dashboard status. A source may also have
    `retrying` (True while its lost device is being reopened: its last sample is then not used)."""

    def latest(self) -> Any: ...

    def status(self) -> str: ...


@dataclass
class SnapshotParts:
    """The fields of one tick's Snapshot while the fills write them; hands as (2, 21, 3)."""

    images: dict[str, np.ndarray] = field(default_factory=dict)
    joints: np.ndarray = field(default_factory=lambda: np.zeros((2, JOINTS_PER_HAND, 3), np.float32))
    joints_valid: np.ndarray = field(default_factory=lambda: np.zeros(2, bool))
    mocap_joints: np.ndarray | None = None
    mocap_valid: np.ndarray | None = None
    pressure_raw: np.ndarray | None = None
    imu_wxyz: np.ndarray | None = None
    glove_present: np.ndarray | None = None
    trackers: dict[str, np.ndarray] = field(default_factory=dict)
    pose_source: str = ""
    joints_confidence: np.ndarray | None = None
    stage_ms: dict[str, float] = field(default_factory=dict)

    def gloves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pressure_raw (2, 256) uint8, imu_wxyz (2, 4) float32, glove_present (2,) bool), zeros at first."""
        if self.pressure_raw is None:
            self.pressure_raw = np.zeros((2, 256), np.uint8)
            self.imu_wxyz = np.zeros((2, 4), np.float32)
            self.glove_present = np.zeros(2, bool)
        return self.pressure_raw, self.imu_wxyz, self.glove_present

    def to_snapshot(self, frame_index: int, t_us: int, status: dict[str, str], ages_ms: dict[str, float]) -> Snapshot:
        mocap = None if self.mocap_joints is None else self.mocap_joints.reshape(2 * JOINTS_PER_HAND, 3)
        return Snapshot(
            frame_index=frame_index, t_us=t_us, images=self.images,
            joints=self.joints.reshape(2 * JOINTS_PER_HAND, 3), joints_valid=self.joints_valid,
            pressure_raw=self.pressure_raw, imu_wxyz=self.imu_wxyz, trackers=self.trackers, source_status=status,
            glove_present=self.glove_present, mocap_joints=mocap, mocap_valid=self.mocap_valid,
            source_age_ms=ages_ms, pose_source=self.pose_source, joints_confidence=self.joints_confidence,
            stage_ms=self.stage_ms,
        )


@dataclass(frozen=True)
class Fill:
    """apply(reading or None, parts) writes a fresh reading (None: its absence) into the parts;
    `reads_trackers` fills run after all the others."""

    apply: Callable[[Any, SnapshotParts], None]
    reads_trackers: bool = False


@dataclass(frozen=True)
class RigInput:
    """One source of the rig: `name` keys its status and age in the Snapshot."""

    name: str
    source: LatestSource
    fill: Fill


def camera_fill(view: str) -> Fill:
    """A CameraReading's (H, W, 3) uint8 RGB image as `images[view]`."""
    if view not in VIEW_NAMES:
        raise ValueError(f"unknown view {view!r}; expected one of {VIEW_NAMES}")

    def apply(reading: Any, parts: SnapshotParts) -> None:
        if reading is not None:
            parts.images[view] = reading.image

    return Fill(apply)


def glove_fill(hand: str) -> Fill:
    """A GloveReading's raw (256,) uint8 and quat_wxyz (4,) float32 (NaN when the glove sent none) as the
    hand's row of `pressure_raw` and `imu_wxyz`."""
    row = HANDS.index(hand)

    def apply(reading: Any, parts: SnapshotParts) -> None:
        raw, imu, present = parts.gloves()
        if reading is not None:
            raw[row], imu[row], present[row] = reading.raw, reading.quat_wxyz, True

    return Fill(apply)


def trackers_fill() -> Fill:
    """A TrackerReading's poses {role: (7,) float32 trans + quaternion w, x, y, z} as `trackers`."""

    def apply(reading: Any, parts: SnapshotParts) -> None:
        if reading is not None:
            parts.trackers.update(reading.poses)

    return Fill(apply)


def mocap_fill(to_model: MocapToModel) -> Fill:
    """A RokokoReading's hands as `mocap_joints` / `mocap_valid`, and through `to_model` (given this tick's
    fresh trackers) as the model's `joints` / `joints_valid`; an invalid hand holds zeros."""

    def apply(reading: Any, parts: SnapshotParts) -> None:
        parts.mocap_joints = np.zeros((2, JOINTS_PER_HAND, 3), np.float32)
        parts.mocap_valid = np.zeros(2, bool)
        parts.pose_source = POSE_FROM_MOCAP
        if reading is None:
            return
        mocap, present = reading.frame.joints, np.asarray(reading.frame.hands_present, bool)
        parts.mocap_joints[present], parts.mocap_valid[:] = mocap[present], present
        joints, valid = to_model(mocap, present, parts.trackers)
        parts.joints_valid = np.asarray(valid, bool).reshape(2)
        parts.joints = np.where(parts.joints_valid[:, None, None], np.asarray(joints, np.float32), 0).astype(np.float32)

    return Fill(apply, reads_trackers=True)


def camera_hands_fill() -> Fill:
    """A CameraHandsReading's estimate as the model's joints, and its frame as `images["ego"]`."""

    def apply(reading: Any, parts: SnapshotParts) -> None:
        if reading is None:
            parts.pose_source, parts.joints_confidence = POSE_FROM_CAMERA, np.zeros(2, np.float32)
            return
        for name, value in reading.estimate.snapshot_fields().items():
            setattr(parts, name, value.reshape(2, JOINTS_PER_HAND, 3) if name == "joints" else value)
        parts.images["ego"] = reading.image

    return Fill(apply)


def fill_order(inputs: Sequence[RigInput]) -> list[RigInput]:
    """The inputs in the order their fills run (those reading the trackers last)."""
    return sorted(inputs, key=lambda rig_input: rig_input.fill.reads_trackers)


def build_snapshot(inputs: Sequence[RigInput], frame_index: int, t_us: int, stale_after_us: int) -> Snapshot:
    """The Snapshot at `t_us` of `inputs` (in `fill_order`): each source's latest reading is used when it
    is at most `stale_after_us` old and the source is not `retrying` a lost device; its status reads
    "ok, age 12 ms", "stale, age 850 ms (<source status>)" (also a young sample of a retrying source, whose
    status then says "disconnected, retrying (…)") or "no sample yet (<source status>)"."""
    parts, status, ages = SnapshotParts(), {}, {}
    for rig_input in inputs:
        reading = rig_input.source.latest()
        if reading is None:
            status[rig_input.name] = f"no sample yet ({rig_input.source.status()})"
        else:
            age_us = max(t_us - reading.t_us, 0)
            ages[rig_input.name] = age_us / 1000
            if age_us > stale_after_us or getattr(rig_input.source, "retrying", False):
                status[rig_input.name] = f"stale, age {age_us / 1000:.0f} ms ({rig_input.source.status()})"
                reading = None
            else:
                status[rig_input.name] = f"ok, age {age_us / 1000:.0f} ms"
        rig_input.fill.apply(reading, parts)
    return parts.to_snapshot(frame_index, t_us, status, ages)
