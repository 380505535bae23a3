"""Studio-like Rokoko datagrams for the tests: full-body actors with realistic extras (body joints, face
shapes, props) around the simulator's hands."""
from __future__ import annotations

import json

import lz4.frame
import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.devices.hardware.rokoko_protocol import HAND_JOINT_NAMES
from touchanything.devices.sim.hand_model import hand_state
from touchanything.devices.sim.script_base import PALM_DOWN, REST_FLEX
from touchanything.devices.sim.shapes import pose_at

BODY_JOINTS = (
    "hip", "spine", "chest", "neck", "head",
    "leftShoulder", "leftUpperArm", "leftLowerArm", "rightShoulder", "rightUpperArm", "rightLowerArm",
    "leftUpLeg", "leftLeg", "leftFoot", "leftToe", "leftToeEnd",
    "rightUpLeg", "rightLeg", "rightFoot", "rightToe", "rightToeEnd",
)
FACE_SHAPES = 52
GLOVE_AT_REST = (np.zeros((2, 256), np.uint8), np.ones(2, bool), np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)))
"""A glove sample (raw, present, quaternions); an episode folder needs a glove or a head video to be found."""
DEADLINE_S = 10.0


def studio_hands() -> np.ndarray:
    """(2, 21, 3) float64 hands of the simulator's kinematic model in Studio coordinates (Y up, Z forward)."""
    hands = [hand_state(side, pose_at(np.array([0.18 * (2 * h - 1), 0.25, 1.05]), PALM_DOWN), REST_FLEX)
             for h, side in enumerate(HANDS)]
    return np.stack([hand.joints[:, [0, 2, 1]] for hand in hands])


def joint_entry(position, rng: np.random.Generator) -> dict:
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    return {"position": dict(zip("xyz", map(float, position))), "rotation": dict(zip("xyzw", map(float, quat)))}


def studio_actor(hands: np.ndarray, present=(True, True), name: str = "Actor1", seed: int = 0,
                 body: bool = True) -> tuple[dict, dict]:
    """A full-body actor as Studio sends it: (actor entry, joint dict)."""
    rng = np.random.default_rng(seed)
    joints = {name_: joint_entry(rng.uniform(-0.5, 1.7, 3), rng) for name_ in BODY_JOINTS} if body else {}
    for h in range(2):
        if present[h]:
            joints.update({n: joint_entry(p, rng) for n, p in zip(HAND_JOINT_NAMES[h], hands[h])})
    meta = {"hasGloves": any(present), "hasLeftGlove": present[0], "hasRightGlove": present[1],
            "hasBody": body, "hasFace": True}
    face = {"faceId": f"{name}_face", **{f"shape{i}": float(rng.uniform(0, 100)) for i in range(FACE_SHAPES)}}
    actor = {"name": name, "color": [255, 120, 0], "meta": meta,
             "dimensions": {"totalHeight": 1.8, "hipHeight": 0.95}, "body": joints, "face": face}
    return actor, joints


def v3_message(actors: list[dict], version: object = "3,0") -> dict:
    prop = {"name": "Stick", "color": [0, 0, 255], "type": 2,
            "position": {"x": 0.1, "y": 1.2, "z": 0.3}, "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
    return {"version": version, "fps": 60.0, "scene": {"timestamp": 12.3456, "actors": actors, "props": [prop]}}


def pack(message: dict, compress: bool = True) -> bytes:
    text = json.dumps(message).encode()
    return lz4.frame.compress(text) if compress else text
