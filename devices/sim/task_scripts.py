"""Scripted tasks: reach → grasp (fingers close until they touch) → hold / lift / press / squeeze / slide →
release → retreat, one- and two-handed, with idle stretches. Produces keyframed hand tracks, object
attachments (an object follows the hand that lifts it) and labelled task segments.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from touchanything.devices.sim.catalogue import CARRY, GRASP, HOLD_PRESS, PRESS, SLIDE, SQUEEZE
from touchanything.devices.sim.hand_model import FINGER_COLUMNS, FINGER_ORDER, PALM_CENTRE, PALM_HALF, THUMB_PAD_ROWS, hand_state
from touchanything.devices.sim.motion import HandTrack, frame_rotation
from touchanything.devices.sim.shapes import Shape, pose_at

SIDES = ("left", "right")
PALM_SURFACE = np.array([PALM_CENTRE[0], PALM_CENTRE[1], PALM_HALF[2]])
REST_FLEX = np.array([0.2, 0.25, 0.25, 0.25, 0.25])
OPEN_FLEX = np.array([0.05, 0.05, 0.05, 0.05, 0.05])
POINT_FLEX = np.array([0.55, 0.0, 0.85, 0.85, 0.85])
PALM_DOWN = frame_rotation((0, 1, 0), (0, 0, -1))


@dataclass
class Attachment:
    obj: int
    hand: int
    start: float
    end: float


@dataclass
class Segment:
    """A labelled stretch of the script: action name and the hands doing it."""

    start: float
    end: float
    action: str
    hands: tuple[int, ...]


@dataclass
class Script:
    tracks: tuple[HandTrack, HandTrack]
    attachments: list[Attachment] = field(default_factory=list)
    segments: list[Segment] = field(default_factory=list)


def rest_position(hand: int) -> np.ndarray:
    return np.array([-0.21 if hand == 0 else 0.21, -0.03, 0.14])


def _mirror(hand: int) -> np.ndarray:
    return np.array([-1.0 if hand == 0 else 1.0, 1.0, 1.0])


def _finger_points(state, finger: int) -> np.ndarray:
    name = FINGER_ORDER[finger]
    col = FINGER_COLUMNS[name]
    cols = np.arange(col, col + 3) if state.side == "left" else 20 - np.arange(col, col + 3)
    rows = [r for r, _, _ in THUMB_PAD_ROWS] if name == "thumb" else [2, 3, 4, 5]
    pads = state.cell_points[np.ix_(rows, cols)].reshape(-1, 3)
    return np.concatenate([pads, state.joints[2 + 4 * finger: 5 + 4 * finger]])


class Planner:
    """Builds a Script over the given objects (their poses may change while attached)."""

    def __init__(self, objects: list[Shape], rng: np.random.Generator) -> None:
        self.objects, self.rng = objects, rng
        self.script = Script((HandTrack(), HandTrack()))
        for hand in (0, 1):
            self.script.tracks[hand].add(0.0, rest_position(hand), PALM_DOWN, REST_FLEX)

    # -- geometry ------------------------------------------------------------------------------------
    def contact_flexion(self, hand: int, position, rotation, shape: Shape, extra: float) -> np.ndarray:
        """Close each finger until it touches `shape`, then `extra` further (the squeeze)."""
        pose = pose_at(position, rotation)
        flex = np.full(5, 0.7)
        grid = np.linspace(0.0, 1.0, 26)
        for finger in range(5):
            trial = REST_FLEX.copy()

            def touching(value: float) -> bool:
                trial[finger] = value
                return shape.sdf(_finger_points(hand_state(SIDES[hand], pose, trial), finger)).min() <= 0.0

            hits = [g for g in grid if touching(g)]
            if not hits:
                continue
            lo, hi = max(hits[0] - grid[1], 0.0), hits[0]
            for _ in range(6):
                mid = (lo + hi) / 2
                lo, hi = (lo, mid) if touching(mid) else (mid, hi)
            flex[finger] = min(hi + extra, 1.0)
        return flex

    def _wrist_for(self, hand: int, rotation: np.ndarray, local_point: np.ndarray, target: np.ndarray) -> np.ndarray:
        """Wrist position that puts the hand-frame `local_point` at world `target`."""
        return target - rotation @ (local_point * _mirror(hand))

    # -- actions -------------------------------------------------------------------------------------
    def reach(self, hand: int, t: float, position, rotation, flexion, duration: float) -> float:
        return self.script.tracks[hand].add(t + duration, position, rotation, flexion)

    def retreat(self, hand: int, t: float) -> float:
        track = self.script.tracks[hand]
        position, rotation, _ = track.last
        t = track.add(t + 0.3, position + rotation[:, 2] * -0.05 + np.array([0, 0, 0.03]), rotation, OPEN_FLEX)
        return track.add(t + 0.6, rest_position(hand), PALM_DOWN, REST_FLEX)

    def side_grip(self, hand: int, shape: Shape, press: float) -> tuple[np.ndarray, np.ndarray]:
        """Wrist pose with the palm against the object's side facing this hand (fingers forward)."""
        centre = shape.pose[:3, 3]
        sign = -1.0 if hand == 0 else 1.0
        reach = shape.size[0]
        rotation = frame_rotation((0, 1, 0), (-sign, 0, 0))
        height = max(0.05, min(centre[2], 0.08))
        target = np.array([centre[0] + sign * (reach - press), centre[1] - 0.01, height])
        return self._wrist_for(hand, rotation, PALM_SURFACE, target), rotation

    def top_grip(self, hand: int, shape: Shape, press: float) -> tuple[np.ndarray, np.ndarray]:
        """Palm down on top of the object (spheres)."""
        top = shape.pose[:3, 3] + np.array([0, -0.01, shape.height - press])
        return self._wrist_for(hand, PALM_DOWN, PALM_SURFACE, top), PALM_DOWN

    def grasp(self, hand: int, t: float, obj: int, lift: bool, squeeze: bool) -> float:
        shape, track = self.objects[obj], self.script.tracks[hand]
        press = self.rng.uniform(0.002, 0.005)
        grip = self.top_grip if shape.kind == "sphere" else self.side_grip
        position, rotation = grip(hand, shape, press)
        flex = self.contact_flexion(hand, position, rotation, shape, self.rng.uniform(0.01, 0.04))
        start = t
        approach = position - rotation[:, 2] * 0.07
        t = self.reach(hand, t, approach, rotation, OPEN_FLEX, 0.8)
        t = track.add(t + 0.35, position, rotation, OPEN_FLEX)
        t = track.add(t + 0.3, position, rotation, flex)
        if lift:
            grab = t
            t = track.add(t + 0.6, position + [0, 0, 0.08], rotation, flex)
            t = track.hold(t + 0.7)
            t = track.add(t + 0.6, position, rotation, flex)
            self.script.attachments.append(Attachment(obj, hand, grab, t))
        if squeeze:
            for _ in range(2):
                t = track.add(t + 0.35, position, rotation, np.minimum(flex + 0.05, 1.0))
                t = track.add(t + 0.35, position, rotation, flex)
        t = track.hold(t + 0.4)
        t = track.add(t + 0.3, position, rotation, OPEN_FLEX)
        end = self.retreat(hand, t)
        self.script.segments.append(Segment(start, end, GRASP if lift else SQUEEZE, (hand,)))
        return end

    def press(self, hand: int, t: float, obj: int, label: str = PRESS) -> float:
        shape, track = self.objects[obj], self.script.tracks[hand]
        angle = np.radians(self.rng.uniform(30, 45))
        rotation = frame_rotation((0, np.cos(angle), -np.sin(angle)), (0, -np.sin(angle), -np.cos(angle)))
        pad = self._pad(hand, rotation, POINT_FLEX, "index", row=2)
        centre = shape.pose[:3, 3]
        jitter = self.rng.uniform(-0.5, 0.5, 2) * np.asarray(shape.size[:2] if shape.kind == "box" else (0.01, 0.01))
        target = np.array([centre[0] + jitter[0], centre[1] + jitter[1], centre[2] + shape.height])
        contact = target - pad
        start = t
        t = self.reach(hand, t, contact + [0, 0, 0.06], rotation, POINT_FLEX, 0.8)
        t = track.add(t + 0.3, contact, rotation, POINT_FLEX)
        for _ in range(int(self.rng.integers(1, 3))):
            depth = self.rng.uniform(0.003, 0.008)
            t = track.add(t + 0.25, contact - [0, 0, depth], rotation, POINT_FLEX)
            t = track.hold(t + 0.4)
            t = track.add(t + 0.25, contact + [0, 0, 0.004], rotation, POINT_FLEX)
        t = track.add(t + 0.2, contact + [0, 0, 0.05], rotation, POINT_FLEX)
        end = self.retreat(hand, t)
        self.script.segments.append(Segment(start, end, label, (hand,)))
        return end

    def slide(self, hand: int, t: float, obj: int) -> float:
        """Flat fingers stroke sideways across the top surface, the wrist raised (fingertip pads touch)."""
        shape, track = self.objects[obj], self.script.tracks[hand]
        tilt = np.radians(10.0)
        rotation = frame_rotation((0, np.cos(tilt), -np.sin(tilt)), (0, -np.sin(tilt), -np.cos(tilt)))
        flat = np.zeros(5)
        centre = shape.pose[:3, 3]
        top = np.array([centre[0], centre[1] + 0.02, centre[2] + shape.height])
        position = top - self._pad(hand, rotation, flat, "middle", row=3)
        depth = self.rng.uniform(0.002, 0.004)
        travel = np.array([min(0.04, shape.size[0] * 0.5), 0.0, 0.0])
        start = t
        t = self.reach(hand, t, position + [0, 0, 0.05], rotation, flat, 0.8)
        t = track.add(t + 0.3, position - [0, 0, depth] - travel, rotation, flat)
        t = track.add(t + 0.8, position - [0, 0, depth] + travel, rotation, flat)
        t = track.add(t + 0.8, position - [0, 0, depth] - travel, rotation, flat)
        t = track.add(t + 0.25, position + [0, 0, 0.04], rotation, flat)
        end = self.retreat(hand, t)
        self.script.segments.append(Segment(start, end, SLIDE, (hand,)))
        return end

    def _pad(self, hand: int, rotation: np.ndarray, flexion: np.ndarray, finger: str, row: int) -> np.ndarray:
        """World offset from the wrist to the middle cell of a finger's pad row, for a hand at the origin."""
        state = hand_state(SIDES[hand], pose_at(np.zeros(3), rotation), flexion)
        col = FINGER_COLUMNS[finger] + 1
        return state.cell_points[row, col if hand == 0 else 20 - col]

    def carry(self, t: float, obj: int) -> float:
        """Both palms press the object's sides, lift it, put it down."""
        shape = self.objects[obj]
        press = self.rng.uniform(0.004, 0.008)
        poses = [self.side_grip(hand, shape, press) for hand in (0, 1)]
        flex = np.full(5, 0.25)
        start = t
        for hand, (position, rotation) in enumerate(poses):
            self.reach(hand, t, position - rotation[:, 2] * 0.06, rotation, flex, 0.8)
            self.script.tracks[hand].add(t + 1.15, position, rotation, flex)
        t += 1.15
        for hand, (position, rotation) in enumerate(poses):
            track = self.script.tracks[hand]
            track.add(t + 0.7, position + [0, 0, 0.1], rotation, flex)
            track.hold(t + 1.5)
            track.add(t + 2.2, position, rotation, flex)
            track.hold(t + 2.4)
        self.script.attachments.append(Attachment(obj, 1, t, t + 2.2))
        end = max(self.retreat(hand, t + 2.4) for hand in (0, 1))
        self.script.segments.append(Segment(start, end, CARRY, (0, 1)))
        return end

    def hold_and_press(self, t: float, obj: int) -> float:
        """The left hand steadies the object from its side; the right index presses its top."""
        shape, left = self.objects[obj], self.script.tracks[0]
        position, rotation = self.side_grip(0, shape, self.rng.uniform(0.002, 0.004))
        flex = self.contact_flexion(0, position, rotation, shape, self.rng.uniform(0.0, 0.02))
        start = t
        t = self.reach(0, t, position - rotation[:, 2] * 0.06, rotation, OPEN_FLEX, 0.8)
        t = left.add(t + 0.3, position, rotation, OPEN_FLEX)
        t = left.add(t + 0.3, position, rotation, flex)
        self.script.tracks[1].hold(t)
        t = self.press(1, t, obj, label=HOLD_PRESS)
        self.script.segments.pop()
        t = left.hold(t)
        t = left.add(t + 0.3, position, rotation, OPEN_FLEX)
        end = self.retreat(0, t)
        self.script.segments.append(Segment(start, end, HOLD_PRESS, (0, 1)))
        return end

    def idle(self, t: float, duration: float) -> float:
        """Hands drift in the air without contact (waypoints that would touch anything are not used)."""
        for hand in (0, 1):
            track = self.script.tracks[hand]
            track.hold(t)
            steps = max(1, int(duration / 0.8))
            for k in range(1, steps + 1):
                track.add(t + duration * k / steps, self._free_waypoint(hand), PALM_DOWN, REST_FLEX)
        self.script.segments.append(Segment(t, t + duration, "idle", ()))
        return t + duration

    def _free_waypoint(self, hand: int) -> np.ndarray:
        for _ in range(10):
            position = rest_position(hand) + self.rng.uniform([-0.05, -0.03, 0.0], [0.05, 0.06, 0.08])
            state = hand_state(SIDES[hand], pose_at(position, PALM_DOWN), REST_FLEX)
            points = np.concatenate([state.joints, state.cell_points[~np.isnan(state.cell_points[..., 0])]])
            if min(shape.sdf(points).min() for shape in self.objects) > 0.02:
                return position
        return rest_position(hand)

    def run(self, action: str, t: float, obj: int, hand: int) -> float:
        """Perform one action on object `obj` (hand used by one-handed actions); returns its end time."""
        for track in self.script.tracks:
            track.hold(t)
        if action == GRASP:
            return self.grasp(hand, t, obj, lift=True, squeeze=False)
        if action == SQUEEZE:
            return self.grasp(hand, t, obj, lift=False, squeeze=True)
        if action == PRESS:
            return self.press(hand, t, obj)
        if action == SLIDE:
            return self.slide(hand, t, obj)
        if action == CARRY:
            return self.carry(t, obj)
        if action == HOLD_PRESS:
            return self.hold_and_press(t, obj)
        raise ValueError(f"unknown action {action!r}")
