"""Rokoko Studio live-stream datagrams (Livestreaming → Custom streaming, JSON v2/v3): decode and encode.

Pure functions, no I/O. Layouts, as read by Rokoko's own plugins (`Rokoko/rokoko-studio-live-blender`
core/live_data_manager.py and `Rokoko/rokoko-studio-live-unity` Assets/Rokoko/Scripts/Core/
JsonLiveSerializerV3.cs):
- v3: `{"version", "fps", "scene": {"timestamp", "actors": [{"name", "meta": {"hasGloves", "hasLeftGlove",
  "hasRightGlove", "hasBody", "hasFace"}, "body": {<joint>: {"position": {x,y,z}, "rotation": {x,y,z,w}}}}],
  "props": [...]}}`.
- v2: `{"version", "timestamp", "props", "trackers", "faces", "actors": [{"name", <joint>: {...}, ...}]}`;
  the joints sit directly on the actor.
The layout is told apart by structure, not by `version`: Studio 1's "JSON v2.5" says version 3 but has
the v2 layout (the Blender plugin handles it the same way). `version` is a number or a string with a comma
or dot decimal ("3,0", "3.0"); only its major number is read, and v1 is refused.

Datagrams starting with the LZ4 frame magic `04 22 4D 18` are LZ4-frame compressed, others are UTF-8 JSON.
Coordinates are kept as Studio sends them: Y up, Z forward, metres.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass

import lz4.frame
import numpy as np

from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.core.snapshot import HANDS

LZ4_MAGIC = b"\x04\x22\x4d\x18"
MAX_JSON_BYTES = 4 * 1024 * 1024
"""Decompressed size limit: a full five-actor scene is far smaller; this only stops decompression bombs."""
FINGERS = ("Thumb", "Index", "Middle", "Ring", "Little")
SEGMENTS = ("Proximal", "Medial", "Distal", "Tip")
IDENTITY_XYZW = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def hand_joint_names(side: str) -> tuple[str, ...]:
    """Studio's names of one hand's 21 joints in the official order (wrist, thumb 1–4, …, pinky 1–4)."""
    return (f"{side}Hand",) + tuple(f"{side}{finger}{segment}" for finger in FINGERS for segment in SEGMENTS)


HAND_JOINT_NAMES = tuple(hand_joint_names(side) for side in HANDS)
"""(left names, right names), 21 each; `Little` is the official pinky."""


class RokokoProtocolError(ValueError):
    """A datagram that is not a usable Rokoko message; `reason` is short, for counters and status lines."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class RokokoFrame:
    """One actor's hands from one datagram.

    joints: (2, 21, 3) float32, left then right, official joint order, Studio coordinates (Y up, Z
        forward, metres); an absent hand holds zeros. Read-only.
    hands_present: (2,) bool, read-only; a hand is present when all 21 joints have finite positions.
    timestamp: Studio's scene time in seconds, when sent. fps: Studio's stream rate, when sent (v3).
    actor: the actor's name ("" when unnamed).
    """

    joints: np.ndarray
    hands_present: np.ndarray
    timestamp: float | None
    fps: float | None
    actor: str


def decode_datagram(data: bytes, actor: str | None = None) -> RokokoFrame:
    """Decode one datagram into the hands of `actor` (by name), or by default of the first actor with any
    hand present (the first actor when none has a hand). Raises RokokoProtocolError when malformed."""
    message = _parse_json(_decompress(data) if data.startswith(LZ4_MAGIC) else data)
    _check_version(message.get("version"))
    scene = message.get("scene", message)
    if not isinstance(scene, dict):
        raise RokokoProtocolError("'scene' is not an object")
    actors = scene.get("actors")
    if not isinstance(actors, list) or not actors:
        raise RokokoProtocolError("no actors")
    frames = (_actor_frame(entry, "scene" in message) for entry in actors)
    if actor is not None:
        chosen = next((f for f in frames if f[0] == actor), None)
        if chosen is None:
            raise RokokoProtocolError(f"no actor named {actor!r}")
    else:
        found = list(frames)
        chosen = next((f for f in found if f[2].any()), found[0])
    name, joints, present = chosen
    joints.flags.writeable = False
    present.flags.writeable = False
    return RokokoFrame(joints, present, _number(scene.get("timestamp")), _number(message.get("fps")), name)


def _decompress(data: bytes) -> bytes:
    decompressor = lz4.frame.LZ4FrameDecompressor()
    try:
        payload = decompressor.decompress(data, max_length=MAX_JSON_BYTES)
    except RuntimeError:
        raise RokokoProtocolError("bad LZ4 frame") from None
    if not decompressor.eof:
        raise RokokoProtocolError("truncated LZ4 frame" if decompressor.needs_input else "LZ4 payload too large")
    return payload


def _parse_json(payload: bytes) -> dict:
    try:
        message = json.loads(payload.decode("utf-8"))
    except UnicodeDecodeError:
        raise RokokoProtocolError("not UTF-8 text") from None
    except (ValueError, RecursionError):
        raise RokokoProtocolError("invalid JSON") from None
    if not isinstance(message, dict):
        raise RokokoProtocolError("not a JSON object")
    return message


def _check_version(value: object) -> None:
    """Accept a major version ≥ 2 given as a number or as "3,0" / "3.0" / "3"."""
    if isinstance(value, str):
        try:
            value = float(value.strip().replace(",", "."))
        except ValueError:
            raise RokokoProtocolError(f"unreadable version {value[:20]!r}") from None
    if _number(value) is None:
        raise RokokoProtocolError("missing or unreadable version")
    if value < 2:
        raise RokokoProtocolError(f"JSON v{int(value)} is not supported (choose JSON v3 in Studio)")


def _number(value: object) -> float | None:
    """A finite JSON number as float, else None (for optional fields)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def _actor_frame(entry: object, v3: bool) -> tuple[str, np.ndarray, np.ndarray]:
    """(name, (2, 21, 3) float32 joints, (2,) present) of one actor entry."""
    if not isinstance(entry, dict):
        raise RokokoProtocolError("an actor is not an object")
    name = entry.get("name", entry.get("id", ""))
    joints_by_name = entry.get("body", {}) if v3 else entry
    if not isinstance(joints_by_name, dict):
        raise RokokoProtocolError("an actor's 'body' is not an object")
    joints = np.zeros((2, JOINTS_PER_HAND, 3), np.float32)
    present = np.zeros(2, bool)
    for h, names in enumerate(HAND_JOINT_NAMES):
        xyz = _hand(joints_by_name, names)
        if xyz is not None:
            joints[h], present[h] = xyz, True
    return name if isinstance(name, str) else "", joints, present


def _hand(joints_by_name: dict, names: tuple[str, ...]) -> np.ndarray | None:
    """(21, 3) float32 positions when every joint is there with finite numbers, else None."""
    rows = []
    for joint_name in names:
        joint = joints_by_name.get(joint_name)
        if joint is None:
            return None
        if not isinstance(joint, dict):
            raise RokokoProtocolError(f"joint {joint_name} is not an object")
        position = joint.get("position")
        if position is None:
            return None
        if not isinstance(position, dict):
            raise RokokoProtocolError(f"joint {joint_name}'s position is not an object")
        rows.append([_coordinate(position.get(axis), joint_name) for axis in "xyz"])
    with np.errstate(over="ignore"):
        xyz = np.array(rows, np.float32)
    return xyz if np.isfinite(xyz).all() else None


def _coordinate(value: object, joint_name: str) -> float:
    """A coordinate as float (NaN when missing or out of range); a non-number is malformed."""
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RokokoProtocolError(f"joint {joint_name} has a non-numeric coordinate")
    number = _number(value)
    return math.nan if number is None else number


def encode_datagram(joints: np.ndarray, hands_present: np.ndarray, *, version: int = 3, compress: bool = True,
                    fps: float = 30, timestamp: float = 0.0, actor: str = "sim") -> bytes:
    """A Studio-like datagram with one actor wearing the present gloves (the other body joints are left out).

    joints: (2, 21, 3) Studio coordinates, left then right; hands_present: (2,) bool (absent hands are not
    sent, as Studio does for a hand without a glove). Positions are written as float32 values, so
    `decode_datagram` returns them bit-exact. Raises ValueError for bad shapes, a version other than 2 or 3,
    or a present hand with non-finite joints.
    """
    joints = np.asarray(joints, np.float32)
    present = np.asarray(hands_present, bool)
    if joints.shape != (2, JOINTS_PER_HAND, 3) or present.shape != (2,):
        raise ValueError(f"expected (2, 21, 3) joints and (2,) presence, got {joints.shape} and {present.shape}")
    body = {
        name: {"position": dict(zip("xyz", xyz)), "rotation": dict(IDENTITY_XYZW)}
        for h in range(2) if present[h] for name, xyz in zip(HAND_JOINT_NAMES[h], joints[h].tolist())
    }
    if version == 3:
        meta = {"hasGloves": bool(present.any()), "hasLeftGlove": bool(present[0]),
                "hasRightGlove": bool(present[1]), "hasBody": False, "hasFace": False}
        message = {"version": 3, "fps": fps, "scene": {
            "timestamp": timestamp, "actors": [{"name": actor, "meta": meta, "body": body}], "props": []}}
    elif version == 2:
        message = {"version": 2, "timestamp": timestamp, "props": [], "trackers": [], "faces": [],
                   "actors": [{"name": actor, **body}]}
    else:
        raise ValueError(f"unknown Rokoko JSON version {version} (expected 2 or 3)")
    text = json.dumps(message, separators=(",", ":"), allow_nan=False).encode("utf-8")
    return lz4.frame.compress(text) if compress else text
