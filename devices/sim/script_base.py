"""What every scripted action builds on: the script's records (hand tracks, attachments, labelled segments),
the hand poses the actions share, and their common geometry (contact flexion, clearance, near-miss offsets,
reach, retreat and idle drifting)."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from touchanything.core.snapshot import FPS, HANDS
from touchanything.devices.sim.hand_model import FINGER_COLUMNS, FINGER_ORDER, PALM_CENTRE, PALM_HALF, THUMB_PAD_ROWS, HandState, hand_state
from touchanything.devices.sim.motion import HandTrack, frame_rotation
from touchanything.devices.sim.shapes import Shape, pose_at
from touchanything.devices.sim.touch import world_sdf

PALM_SURFACE = np.array([PALM_CENTRE[0], PALM_CENTRE[1], PALM_HALF[2]])
REST_FLEX = np.array([0.2, 0.25, 0.25, 0.25, 0.25])
OPEN_FLEX = np.array([0.05, 0.05, 0.05, 0.05, 0.05])
POINT_FLEX = np.array([0.55, 0.0, 0.85, 0.85, 0.85])
PALM_DOWN = frame_rotation((0, 1, 0), (0, 0, -1))
UP = np.array([0.0, 0.0, 1.0])
CLEARANCE = 0.005
"""A near-miss keeps every joint and tactile point of the hand at least this far (metres) from every surface."""
GAP_STEP = 0.005
MAX_GAP = 0.1


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


REST_POSITIONS = ((-0.21, -0.03, 0.14), (0.21, -0.03, 0.14))
"""Where each hand waits, raised when an object (a tall one, scaled up) would come within 2 cm of it."""
REST_CLEARANCE = 0.02
PATH_CLEARANCE = 0.01
PATH_SAMPLES = 8
OVERHEAD = 0.08
"""A move whose straight path would pass within 1 cm of an object goes over it, this high above the tallest."""


def mirror(hand: int) -> np.ndarray:
    return np.array([-1.0 if hand == 0 else 1.0, 1.0, 1.0])


def hand_points(state: HandState) -> np.ndarray:
    """(N, 3) the joints and tactile points of a posed hand."""
    return np.concatenate([state.joints, state.cell_points[~np.isnan(state.cell_points[..., 0])]])


def _finger_points(state: HandState, finger: int) -> np.ndarray:
    name = FINGER_ORDER[finger]
    col = FINGER_COLUMNS[name]
    cols = np.arange(col, col + 3) if state.side == "left" else 20 - np.arange(col, col + 3)
    rows = [r for r, _, _ in THUMB_PAD_ROWS] if name == "thumb" else [2, 3, 4, 5]
    pads = state.cell_points[np.ix_(rows, cols)].reshape(-1, 3)
    return np.concatenate([pads, state.joints[2 + 4 * finger: 5 + 4 * finger]])


class ScriptBuilder:
    """Keyframes for both hands over the given objects (their poses change when an action moves them)."""

    def __init__(self, objects: list[Shape], rng: np.random.Generator) -> None:
        self.objects, self.rng = objects, rng
        self.script = Script((HandTrack(), HandTrack()))
        self.rest_at = [self._raised(hand, np.array(p, float)) for hand, p in enumerate(REST_POSITIONS)]
        for hand in (0, 1):
            self.script.tracks[hand].add(0.0, self.rest_at[hand], PALM_DOWN, REST_FLEX)

    def _raised(self, hand: int, position: np.ndarray) -> np.ndarray:
        while self.clearance(hand, position, PALM_DOWN, REST_FLEX) < REST_CLEARANCE and position[2] < 0.4:
            position = position + 0.01 * UP
        return position

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
                return shape.sdf(_finger_points(hand_state(HANDS[hand], pose, trial), finger)).min() <= 0.0

            hits = [g for g in grid if touching(g)]
            if not hits:
                continue
            lo, hi = max(hits[0] - grid[1], 0.0), hits[0]
            for _ in range(6):
                mid = (lo + hi) / 2
                lo, hi = (lo, mid) if touching(mid) else (mid, hi)
            flex[finger] = min(hi + extra, 1.0)
        return flex

    def side_grip(self, hand: int, shape: Shape, press: float) -> tuple[np.ndarray, np.ndarray]:
        """Wrist pose with the palm `press` metres into the object's side facing this hand (fingers forward)."""
        centre = shape.pose[:3, 3]
        sign = -1.0 if hand == 0 else 1.0
        rotation = frame_rotation((0, 1, 0), (-sign, 0, 0))
        height = max(0.05, min(centre[2], 0.08))
        target = np.array([centre[0] + sign * (shape.size[0] - press), centre[1] - 0.01, height])
        return self.wrist_for(hand, rotation, PALM_SURFACE, target), rotation

    def wrist_for(self, hand: int, rotation: np.ndarray, local_point: np.ndarray, target: np.ndarray) -> np.ndarray:
        """Wrist position that puts the hand-frame `local_point` at world `target`."""
        return target - rotation @ (local_point * mirror(hand))

    def pad(self, hand: int, rotation: np.ndarray, flexion: np.ndarray, finger: str, row: int) -> np.ndarray:
        """World offset from the wrist to the middle cell of a finger's pad row, for a hand at the origin."""
        state = hand_state(HANDS[hand], pose_at(np.zeros(3), rotation), flexion)
        col = FINGER_COLUMNS[finger] + 1
        return state.cell_points[row, col if hand == 0 else 20 - col]

    def clearance(self, hand: int, position, rotation: np.ndarray, flexion: np.ndarray, shapes: list[Shape] | None = None,
                  table: bool = True) -> float:
        """The smallest distance (metres) from the hand's joints and tactile points to the objects (or only
        `shapes`) and, with `table`, the table top."""
        points = hand_points(hand_state(HANDS[hand], pose_at(position, rotation), flexion))
        shapes = self.objects if shapes is None else shapes
        if table:
            return float(world_sdf(points, shapes).min())
        return min((float(shape.sdf(points).min()) for shape in shapes), default=np.inf)

    def near_miss_gap(self, hand: int, positions: list[np.ndarray], rotation: np.ndarray, flexions: list[np.ndarray],
                      direction: np.ndarray, gap: float) -> float | None:
        """The offset (≥ gap) along `direction` at which every pose (each position with each flexion) keeps
        `CLEARANCE` from every surface, raised in 5 mm steps; None when there is none within 10 cm."""
        while gap < MAX_GAP:
            if all(self.clearance(hand, p + gap * direction, rotation, f) >= CLEARANCE for p in positions for f in flexions):
                return gap
            gap += GAP_STEP
        return None

    def first_touch(self, hand: int, position: np.ndarray, rotation: np.ndarray, flexion: np.ndarray,
                    direction: np.ndarray) -> np.ndarray:
        """The wrist position along `direction` from `position` (which must be clear), within 30 cm, at which
        the hand's tactile points first touch a surface (1 mm bisection)."""
        lo, hi = 0.0, 0.3
        while hi - lo > 0.001:
            mid = (lo + hi) / 2
            state = hand_state(HANDS[hand], pose_at(position + mid * direction, rotation), flexion)
            cells = state.cell_points[~np.isnan(state.cell_points[..., 0])]
            lo, hi = (lo, mid) if world_sdf(cells, self.objects).min() <= 0.0 else (mid, hi)
        return position + hi * direction

    # -- motion --------------------------------------------------------------------------------------
    def reach(self, hand: int, t: float, position, rotation, flexion, duration: float) -> float:
        """Move to the pose in `duration` seconds; over the objects when the straight path (checked with the
        target's orientation and flexion) would pass within `PATH_CLEARANCE` of one."""
        track = self.script.tracks[hand]
        start = track.positions[-1]
        path = [start + s * (np.asarray(position) - start) for s in np.linspace(0.0, 1.0, PATH_SAMPLES)[1:-1]]
        if any(self.clearance(hand, p, rotation, flexion, table=False) < PATH_CLEARANCE for p in path):
            top = max(float(shape.pose[2, 3] + shape.height) for shape in self.objects)
            over = (start + np.asarray(position)) / 2
            over[2] = max(start[2], position[2], top + OVERHEAD)
            track.add(t + duration / 2, over, rotation, flexion)
        return track.add(t + duration, position, rotation, flexion)

    def retreat(self, hand: int, t: float) -> float:
        track = self.script.tracks[hand]
        position, rotation, _ = track.last
        t = track.add(t + 0.3, position + rotation[:, 2] * -0.05 + np.array([0, 0, 0.03]), rotation, OPEN_FLEX)
        return self.reach(hand, t, self.rest_at[hand], PALM_DOWN, REST_FLEX, 0.6)

    def touches(self, hand: int, start: float, end: float) -> bool:
        """Whether the hand's tactile points touch a surface at any frame (30 Hz) from `start` to `end`, the
        objects where they are now."""
        positions, rotations, flexion = self.script.tracks[hand].sample(np.arange(start, end, 1.0 / FPS))
        for position, rotation, flex in zip(positions, rotations, flexion):
            state = hand_state(HANDS[hand], pose_at(position, rotation), flex)
            if world_sdf(state.cell_points[~np.isnan(state.cell_points[..., 0])], self.objects).min() <= 0.0:
                return True
        return False

    def snapshot(self) -> tuple[Script, list[np.ndarray]]:
        return copy.deepcopy(self.script), [shape.pose.copy() for shape in self.objects]

    def restore(self, saved: tuple[Script, list[np.ndarray]]) -> None:
        self.script = copy.deepcopy(saved[0])
        for shape, pose in zip(self.objects, saved[1]):
            shape.pose = pose.copy()

    def attach(self, obj: int, hand: int, start: float, end: float) -> None:
        """The object follows the hand rigidly from `start` to `end`."""
        self.script.attachments.append(Attachment(obj, hand, start, end))

    def label(self, start: float, end: float, action: str, hands: tuple[int, ...]) -> float:
        """Record a labelled segment; returns its end."""
        self.script.segments.append(Segment(start, end, action, hands))
        return end

    def idle(self, t: float, duration: float) -> float:
        """Hands drift in the air without contact (waypoints that would touch anything are not used)."""
        for hand in (0, 1):
            track = self.script.tracks[hand]
            track.hold(t)
            steps = max(1, int(duration / 0.8))
            for k in range(1, steps + 1):
                track.add(t + duration * k / steps, self._free_waypoint(hand), PALM_DOWN, REST_FLEX)
        return self.label(t, t + duration, "idle", ())

    def _free_waypoint(self, hand: int) -> np.ndarray:
        for _ in range(10):
            position = self.rest_at[hand] + self.rng.uniform([-0.05, -0.03, 0.0], [0.05, 0.06, 0.08])
            if self.clearance(hand, position, PALM_DOWN, REST_FLEX) > REST_CLEARANCE:
                return position
        return self.rest_at[hand]
