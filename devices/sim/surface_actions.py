"""Actions on a surface — an object's top or a spot on the table: press with the index finger (or hover over
the surface, or hover and then press), slide flat fingers, rest the flat hand on it (or just above it), and
push an object along the table (or miss it). A near-miss variant runs the same keyframes as its action, raised
or backed off so that no point of the hand comes within `CLEARANCE` of a surface, so the pose sequence alone
does not say whether the hand touched."""
from __future__ import annotations

import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.devices.sim.cameras import wrist_camera
from touchanything.devices.sim.catalogue import AIR_PUSH, HOVER, HOVER_PRESS, PRESS, PUSH, REST, REST_HOVER, SLIDE
from touchanything.devices.sim.hand_model import hand_state
from touchanything.devices.sim.motion import frame_rotation
from touchanything.devices.sim.script_base import CLEARANCE, POINT_FLEX, UP, ScriptBuilder, hand_points
from touchanything.devices.sim.shapes import pose_at
from touchanything.devices.sim.touch import world_sdf
from touchanything.devices.sim.world import TABLE_Y

HOVER_GAP = (0.01, 0.03)
"""A hovering fingertip stays this far (metres) above the surface at its lowest."""
REST_HOVER_GAP = (0.01, 0.025)
AIR_PUSH_GAP = (0.02, 0.04)
SOFT_DEPTH = (0.01, 0.025)
"""How far a press or a resting hand goes into a soft object (it gives way by its softness share of this)."""
PUSH_LENGTH = (0.04, 0.08)
PUSH_ROOM = 0.03
"""A pushed object ends at least this far from the other objects and the table's far edge."""
PUSH_FINGERTIP = 0.015
"""A pushing hand's lowest point stays this high above the table (lower objects are pushed 1 cm below their top)."""
FORWARD = np.array([0.0, 1.0, 0.0])
"""Pushes go away from the person."""

Where = int | np.ndarray
"""An object's index, or a (3,) point on the table."""


def _tilted(degrees: float) -> np.ndarray:
    """Palm down, fingers pointing forward and `degrees` down."""
    a = np.radians(degrees)
    return frame_rotation((0, np.cos(a), -np.sin(a)), (0, -np.sin(a), -np.cos(a)))


class SurfaceActions(ScriptBuilder):
    def table_spot(self, hand: int) -> np.ndarray | None:
        """A point on the table on this hand's side, at least 8 cm from every object (None if none found)."""
        sign = -1.0 if hand == 0 else 1.0
        for _ in range(10):
            spot = np.array([sign * self.rng.uniform(0.04, 0.2), self.rng.uniform(0.08, 0.34), 0.0])
            if min(shape.sdf(spot[None] + 0.01 * UP)[0] for shape in self.objects) > 0.08:
                return spot
        return None

    def _surface(self, where: Where, spread: float) -> tuple[np.ndarray, float]:
        """A target point on the surface and the surface's softness: the table spot itself, or a point on the
        object's top within `spread` of its half size (1 cm for round tops)."""
        if not isinstance(where, int):
            return np.asarray(where, float), 0.0
        shape = self.objects[where]
        half = np.asarray(shape.size[:2]) if shape.kind == "box" else np.array([0.01, 0.01])
        jitter = self.rng.uniform(-spread, spread, 2) * half
        centre = shape.pose[:3, 3]
        return np.array([centre[0] + jitter[0], centre[1] + jitter[1], centre[2] + shape.height]), shape.softness

    def _depth(self, soft: float, rigid: tuple[float, float]) -> float:
        return self.rng.uniform(*SOFT_DEPTH) if soft else self.rng.uniform(*rigid)

    def press(self, hand: int, t: float, where: Where, variant: str = PRESS, label: str | None = None) -> float:
        """Point with the index finger and press the surface once or twice. HOVER: the same keyframes raised so
        that the fingertip stays 1–3 cm above the surface; HOVER_PRESS: hold still 1–3 cm above, then press."""
        track = self.script.tracks[hand]
        angle = np.radians(self.rng.uniform(30, 45))
        rotation = frame_rotation((0, np.cos(angle), -np.sin(angle)), (0, -np.sin(angle), -np.cos(angle)))
        target, soft = self._surface(where, 0.5)
        contact = target - self.pad(hand, rotation, POINT_FLEX, "index", row=2)
        depths = [self._depth(soft, (0.003, 0.008)) for _ in range(int(self.rng.integers(1, 3)))]
        approach = self.rng.uniform(0.04, 0.08)
        gap = self.near_miss_gap(hand, [contact], rotation, [POINT_FLEX], UP, self.rng.uniform(*HOVER_GAP))
        variant = PRESS if gap is None else variant
        base = contact + (gap + max(depths)) * UP if variant == HOVER else contact
        start = t
        t = self.reach(hand, t, base + approach * UP, rotation, POINT_FLEX, 0.8)
        if variant == HOVER_PRESS:
            t = track.add(t + 0.3, contact + gap * UP, rotation, POINT_FLEX)
            t = track.hold(t + self.rng.uniform(0.4, 1.0))
        t = track.add(t + 0.3, base, rotation, POINT_FLEX)
        for depth in depths:
            t = track.add(t + 0.25, base - depth * UP, rotation, POINT_FLEX)
            t = track.hold(t + 0.4)
            t = track.add(t + 0.25, base + 0.004 * UP, rotation, POINT_FLEX)
        t = track.add(t + 0.2, base + 0.05 * UP, rotation, POINT_FLEX)
        return self.label(start, self.retreat(hand, t), label or variant, (hand,))

    def slide(self, hand: int, t: float, obj: int) -> float:
        """Flat fingers stroke sideways across the top surface, the wrist raised (fingertip pads touch)."""
        shape, track = self.objects[obj], self.script.tracks[hand]
        rotation = _tilted(10.0)
        flat = np.zeros(5)
        centre = shape.pose[:3, 3]
        top = np.array([centre[0], centre[1] + 0.02, centre[2] + shape.height])
        position = top - self.pad(hand, rotation, flat, "middle", row=3)
        depth = self.rng.uniform(0.002, 0.004)
        travel = np.array([min(0.04, shape.size[0] * 0.5), 0.0, 0.0])
        start = t
        t = self.reach(hand, t, position + [0, 0, 0.05], rotation, flat, 0.8)
        t = track.add(t + 0.3, position - [0, 0, depth] - travel, rotation, flat)
        t = track.add(t + 0.8, position - [0, 0, depth] + travel, rotation, flat)
        t = track.add(t + 0.8, position - [0, 0, depth] - travel, rotation, flat)
        t = track.add(t + 0.25, position + [0, 0, 0.04], rotation, flat)
        return self.label(start, self.retreat(hand, t), SLIDE, (hand,))

    def rest(self, hand: int, t: float, where: Where, variant: str = REST) -> float:
        """Lower the flat hand (fingers forward, tilted down 10–14° so the wrist camera stays clear of the
        surface) until it touches, press in 3–6 mm (1–2.5 cm into a soft object), hold, lift. REST_HOVER: the
        same keyframes held 1–2.5 cm above the surface."""
        track = self.script.tracks[hand]
        flat = np.array([self.rng.uniform(0.1, 0.3), *np.full(4, self.rng.uniform(0.0, 0.08))])
        target, soft = self._surface(where, 0.3)
        depth = self._depth(soft, (0.003, 0.006))
        for tilt in np.arange(self.rng.uniform(10.0, 14.0), 30.0, 3.0):
            rotation = _tilted(tilt)
            above = target - self.pad(hand, rotation, flat, "middle", row=3) + 0.06 * UP
            contact = self.first_touch(hand, above, rotation, flat, -UP)
            if self._camera_clear(hand, contact - depth * UP, rotation):
                break
        gap = self.near_miss_gap(hand, [contact], rotation, [flat], UP, self.rng.uniform(*REST_HOVER_GAP))
        variant = REST if gap is None else variant
        base = contact + (depth + gap) * UP if variant == REST_HOVER else contact
        start = t
        t = self.reach(hand, t, base + self.rng.uniform(0.04, 0.08) * UP, rotation, flat, 0.8)
        t = track.add(t + 0.35, base - depth * UP, rotation, flat)
        t = track.hold(t + self.rng.uniform(0.6, 1.2))
        t = track.add(t + 0.3, base + 0.05 * UP, rotation, flat)
        return self.label(start, self.retreat(hand, t), variant, (hand,))

    def _camera_clear(self, hand: int, position: np.ndarray, rotation: np.ndarray) -> bool:
        """Whether the wrist camera of a hand at this pose is at least `CLEARANCE` outside every surface."""
        centre = wrist_camera(HANDS[hand], pose_at(position, rotation)).centre
        return bool(world_sdf(centre[None], self.objects)[0] >= CLEARANCE)

    def push(self, hand: int, t: float, obj: int, variant: str = PUSH) -> float:
        """The hand on the object's side, fingers pointing down, presses its pads 3–6 mm into the object's near
        face and pushes it 4–8 cm away along the table. AIR_PUSH: the same stroke 2–4 cm short of the object,
        which stays put. Without room to push, a press on the object's top (a hover for an air push)."""
        shape = self.objects[obj]
        hand = int(shape.pose[0, 3] > 0)
        track = self.script.tracks[hand]
        tilt = np.radians(self.rng.uniform(10.0, 25.0))
        rotation = frame_rotation((0, np.sin(tilt), -np.cos(tilt)), (0, np.cos(tilt), np.sin(tilt)))
        flex = np.array([self.rng.uniform(0.2, 0.4), *np.full(4, self.rng.uniform(0.05, 0.2))])
        centre = shape.pose[:3, 3]
        pad = self.pad(hand, rotation, flex, "middle", row=3)
        top = centre[2] + shape.height
        height = min(PUSH_FINGERTIP + (pad - self._lowest(hand, rotation, flex))[2], top - 0.01)
        start_at = np.array([centre[0], centre[1] - shape.size[1 if shape.kind == "box" else 0] - 0.08, height]) - pad
        contact = self.first_touch(hand, start_at, rotation, flex, FORWARD) + self.rng.uniform(0.003, 0.006) * FORWARD
        length = self._push_length(hand, obj, contact, rotation, flex)
        gap = self.near_miss_gap(hand, [contact, contact + length * FORWARD], rotation, [flex], -FORWARD, self.rng.uniform(*AIR_PUSH_GAP))
        if length < 0.02 or (variant == AIR_PUSH and gap is None):
            return self.press(hand, t, obj, HOVER if variant == AIR_PUSH else PRESS)
        base = contact - (gap if variant == AIR_PUSH else 0.0) * FORWARD
        start = t
        t = self.reach(hand, t, base - 0.06 * FORWARD, rotation, flex, 0.8)
        grab = track.add(t + 0.35, base, rotation, flex)
        t = track.add(grab + self.rng.uniform(0.8, 1.2), base + length * FORWARD, rotation, flex)
        if variant == PUSH:
            self.attach(obj, hand, grab, t)
            shape.pose = pose_at(centre + length * FORWARD, shape.pose[:3, :3])
        t = track.hold(t + 0.2)
        t = track.add(t + 0.3, base + (length - 0.05) * FORWARD + 0.02 * UP, rotation, flex)
        return self.label(start, self.retreat(hand, t), variant, (hand,))

    def _lowest(self, hand: int, rotation: np.ndarray, flex: np.ndarray) -> np.ndarray:
        """The lowest joint or tactile point of a hand posed at the origin."""
        points = hand_points(hand_state(HANDS[hand], pose_at(np.zeros(3), rotation), flex))
        return points[np.argmin(points[:, 2])]

    def _push_length(self, hand: int, obj: int, contact: np.ndarray, rotation: np.ndarray, flex: np.ndarray) -> float:
        """The longest stroke (from 4–8 cm down in 1 cm steps) that leaves the object `PUSH_ROOM` from the
        others and on the table, the hand clear of the others; 0 when there is none."""
        shape, others = self.objects[obj], [o for k, o in enumerate(self.objects) if k != obj]
        corners = shape.faces().vertices.reshape(-1, 3) if shape.kind != "sphere" else shape.pose[None, :3, 3]
        length = self.rng.uniform(*PUSH_LENGTH)
        while length >= 0.02:
            moved = corners + length * FORWARD
            room = min(o.sdf(moved).min() for o in others)
            on_table = moved[:, 1].max() < TABLE_Y[1] - PUSH_ROOM
            if room >= PUSH_ROOM and on_table and self.clearance(hand, contact + length * FORWARD, rotation, flex, others) >= CLEARANCE:
                return length
            length -= 0.01
        return 0.0
