"""The JSON-lines streams of a raw EgoTouch episode: hand poses, Vive trackers and JQ glove samples.

Schemas (one object per line; the line number is the frame index):
- `wilor_hands.json`, `rokoko_hands.json`: `{"frame_index", "left_pos": 21×3 | [], "right_pos": 21×3 | []}`.
- `vive_poses.json`: `{"frame_index", "poses": {role: {"trans": [3], "rot": [4]}}}` for roles chest,
  left_wrist, right_wrist; quaternion order w, x, y, z.
- `jq_pressure.json` (the official schema is not released; this is ours): `{"frame_index",
  "timestamp_us", "left": {"raw": 256 ints 0–255, "quat_wxyz": [4]} | null, "right": … | null}`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.core.hand_pose import JOINTS_PER_HAND, hand_from_json
from touchanything.core.snapshot import HANDS, TRACKER_ROLES
from touchanything.devices.episodes.jsonl import FieldProblems, read_jsonl_lines, where

IDENTITY_WXYZ = (1.0, 0.0, 0.0, 0.0)


def fit_length(array: np.ndarray, frames: int, fill: float | bool = 0) -> np.ndarray:
    """Cut or pad (with `fill`) the first axis of `array` to `frames`."""
    if array.shape[0] >= frames:
        return array[:frames]
    pad = np.full((frames - array.shape[0],) + array.shape[1:], fill, dtype=array.dtype)
    return np.concatenate([array, pad])


@dataclass
class HandStream:
    """joints: (N, 2, 21, 3) float32 (zeros where invalid); valid: (N, 2) bool."""

    joints: np.ndarray
    valid: np.ndarray

    def fit(self, frames: int) -> HandStream:
        """Cut or pad (invalid) to `frames`."""
        return HandStream(fit_length(self.joints, frames), fit_length(self.valid, frames, False))


@dataclass
class TrackerStream:
    """poses: (N, 3, 7) float32 trans + rot per role (zeros where missing); valid: (N, 3) bool."""

    poses: np.ndarray
    valid: np.ndarray

    def fit(self, frames: int) -> TrackerStream:
        """Cut or pad (invalid) to `frames`."""
        return TrackerStream(fit_length(self.poses, frames), fit_length(self.valid, frames, False))


@dataclass
class GloveStream:
    """raw: (N, 2, 256) uint8; present: (N, 2) bool; quat_wxyz: (N, 2, 4) float32; timestamps_us: (N,).
    broken: the numbers of the lines that are not a JSON object; dropped: the hand samples left out, by field."""

    raw: np.ndarray
    present: np.ndarray
    quat_wxyz: np.ndarray
    timestamps_us: np.ndarray | None
    broken: list[int] = field(default_factory=list)
    dropped: FieldProblems | None = None

    def fit(self, frames: int) -> GloveStream:
        """Cut or pad (absent, identity quaternion) to `frames`."""
        quat = fit_length(self.quat_wxyz, frames, 0.0)
        quat[np.all(quat == 0, axis=-1)] = IDENTITY_WXYZ
        stamps = self.timestamps_us
        return GloveStream(fit_length(self.raw, frames), fit_length(self.present, frames, False), quat,
                           None if stamps is None or len(stamps) < frames else stamps[:frames], self.broken, self.dropped)

    def skipped(self) -> str | None:
        """What no computation from this stream uses, as one line: `N glove samples skipped: malformed lines (2
        lines, first line 5); left: … (line 4)` (a broken line counts as one sample); None when nothing was."""
        dropped = self.dropped.count() if self.dropped else 0
        if not self.broken and not dropped:
            return None
        reasons = [f"malformed lines ({where(self.broken)})"] if self.broken else []
        reasons += self.dropped.lines(path=False) if self.dropped else []
        count = len(self.broken) + dropped
        return f"{count} glove sample{'s' if count != 1 else ''} skipped: {'; '.join(reasons)}"


def _hand(value: object) -> tuple[np.ndarray, bool]:
    """`hand_from_json`, with numbers beyond float range (JSON integers are unbounded) an invalid hand."""
    try:
        return hand_from_json(value)
    except OverflowError:
        return np.zeros((JOINTS_PER_HAND, 3), np.float32), False


def read_hands(path: Path) -> tuple[HandStream, list[str]]:
    """Read a WiLoR or Rokoko stream; a hand failing the official validity rule is invalid (zeros)."""
    rows, line_numbers, problems, _ = read_jsonl_lines(path)
    joints = np.zeros((len(rows), 2, JOINTS_PER_HAND, 3), np.float32)
    valid = np.zeros((len(rows), 2), bool)
    bad = FieldProblems(path)
    for i, row in enumerate(rows):
        for h, hand in enumerate(HANDS):
            value = (row or {}).get(f"{hand}_pos")
            joints[i, h], valid[i, h] = _hand(value)
            if value not in (None, []) and not valid[i, h]:
                bad.add(f"{hand}_pos", line_numbers[i], "not 21 finite joints within the official bounds; hand marked invalid")
    return HandStream(joints, valid), problems + bad.lines()


def hands_row(frame_index: int, joints: np.ndarray, valid: np.ndarray) -> dict:
    """One line of a hands stream from (2, 21, 3) joints and (2,) validity."""
    row: dict = {"frame_index": int(frame_index)}
    for h, hand in enumerate(HANDS):
        row[f"{hand}_pos"] = np.asarray(joints[h], np.float32).tolist() if valid[h] else []
    return row


def _floats(value: object, size: int) -> np.ndarray | None:
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return None
    return out if out.shape == (size,) and np.all(np.isfinite(out)) else None


def read_trackers(path: Path) -> tuple[TrackerStream, list[str]]:
    """Read `vive_poses.json`; a role that is missing or malformed gives 7 zeros and valid = False."""
    rows, line_numbers, problems, _ = read_jsonl_lines(path)
    poses = np.zeros((len(rows), len(TRACKER_ROLES), 7), np.float32)
    valid = np.zeros((len(rows), len(TRACKER_ROLES)), bool)
    bad = FieldProblems(path)
    for i, row in enumerate(rows):
        entries = (row or {}).get("poses") or {}
        for r, role in enumerate(TRACKER_ROLES):
            entry = entries.get(role) if isinstance(entries, dict) else None
            if entry is None:
                continue
            trans = _floats(entry.get("trans") if isinstance(entry, dict) else None, 3)
            rot = _floats(entry.get("rot") if isinstance(entry, dict) else None, 4)
            if trans is None or rot is None or np.linalg.norm(rot) < 1e-6:
                bad.add(f"poses.{role}", line_numbers[i], "expected trans[3] and rot[4] finite numbers, rot of non-zero "
                        "length; pose dropped")
                continue
            poses[i, r] = np.concatenate([trans, rot])
            valid[i, r] = True
    return TrackerStream(poses, valid), problems + bad.lines()


def trackers_row(frame_index: int, poses: np.ndarray, valid: np.ndarray) -> dict:
    """One line of `vive_poses.json` from (3, 7) poses and (3,) validity."""
    entries = {
        role: {"trans": poses[r, :3].tolist(), "rot": poses[r, 3:].tolist()}
        for r, role in enumerate(TRACKER_ROLES) if valid[r]
    }
    return {"frame_index": int(frame_index), "poses": entries}


def _glove_sample(entry: object) -> tuple[np.ndarray, np.ndarray] | tuple[str, str]:
    """(raw uint8, quaternion) of one hand's sample, or (field, what is wrong). A missing `quat_wxyz` is the
    identity; one that is present must be 4 finite numbers of non-zero length (never silently replaced)."""
    raw = _floats(entry.get("raw"), 256) if isinstance(entry, dict) else None
    if raw is None or raw.min() < 0 or raw.max() > 255 or np.any(raw != np.round(raw)):
        return "", "expected raw[256] integers 0–255 and quat_wxyz[4]; sample dropped"
    if "quat_wxyz" not in entry:
        return raw.astype(np.uint8), np.array(IDENTITY_WXYZ)
    quat = _floats(entry["quat_wxyz"], 4)
    if quat is None or np.linalg.norm(quat) < 1e-6:
        text = repr(entry["quat_wxyz"])
        return ".quat_wxyz", f"{text if len(text) <= 60 else text[:57] + '...'} is not 4 finite numbers of non-zero length; sample dropped"
    return raw.astype(np.uint8), quat


def read_glove(path: Path) -> tuple[GloveStream, list[str]]:
    """Read `jq_pressure.json`; a malformed hand sample counts as absent in that frame."""
    rows, line_numbers, problems, broken = read_jsonl_lines(path)
    n = len(rows)
    raw = np.zeros((n, 2, 256), np.uint8)
    present = np.zeros((n, 2), bool)
    quat = np.tile(np.array(IDENTITY_WXYZ, np.float32), (n, 2, 1))
    stamps = np.full(n, -1, np.int64)
    bad, dropped = FieldProblems(path), FieldProblems(path)
    for i, row in enumerate(rows):
        row = row or {}
        stamp = row.get("timestamp_us")
        if isinstance(stamp, int) and not isinstance(stamp, bool) and 0 <= stamp < 2**63:
            stamps[i] = stamp
        elif stamp is not None:
            bad.add("timestamp_us", line_numbers[i], "expected an integer number of µs ≥ 0; glove times not used")
        for h, hand in enumerate(HANDS):
            if row.get(hand) is None:
                continue
            sample = _glove_sample(row[hand])
            if isinstance(sample[0], str):
                dropped.add(hand + sample[0], line_numbers[i], sample[1])
                continue
            raw[i, h], quat[i, h] = sample
            present[i, h] = True
    timestamps = stamps if n and np.all(stamps >= 0) else None
    return GloveStream(raw, present, quat, timestamps, broken, dropped), problems + bad.lines() + dropped.lines()


def glove_row(frame_index: int, timestamp_us: int, raw: np.ndarray, present: np.ndarray,
              quat_wxyz: np.ndarray) -> dict:
    """One line of `jq_pressure.json` from (2, 256) uint8 raw, (2,) presence and (2, 4) quaternions. A
    quaternion the glove did not send (NaN, or all zeros) is left out of the line: the sample's pressure is
    kept, and a reader takes the missing orientation as the identity."""
    row: dict = {"frame_index": int(frame_index), "timestamp_us": int(timestamp_us)}
    for h, hand in enumerate(HANDS):
        if not present[h]:
            row[hand] = None
            continue
        row[hand] = {"raw": np.asarray(raw[h], np.uint8).tolist()}
        quat = np.asarray(quat_wxyz[h], np.float32)
        if np.all(np.isfinite(quat)) and np.linalg.norm(quat) >= 1e-6:
            row[hand]["quat_wxyz"] = quat.tolist()
    return row
