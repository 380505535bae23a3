"""Grasping actions: hold (grasp and lift), squeeze, their near miss (the same grasp closing in the air a few
centimetres short of the object, which then stays where it is), and the two-handed carry."""
from __future__ import annotations

import numpy as np

from touchanything.devices.sim.catalogue import CARRY, GRASP, MISS, SQUEEZE
from touchanything.devices.sim.script_base import OPEN_FLEX, PALM_DOWN, PALM_SURFACE, ScriptBuilder
from touchanything.devices.sim.shapes import Shape

MISS_GAP = (0.015, 0.04)
"""A missed grasp stops this far (metres) short of the object, along the palm normal."""


class GraspActions(ScriptBuilder):
    def top_grip(self, hand: int, shape: Shape, press: float) -> tuple[np.ndarray, np.ndarray]:
        """Palm down on top of the object (spheres)."""
        top = shape.pose[:3, 3] + np.array([0, -0.01, shape.height - press])
        return self.wrist_for(hand, PALM_DOWN, PALM_SURFACE, top), PALM_DOWN

    def grasp(self, hand: int, t: float, obj: int, lift: bool, squeeze: bool, miss: bool = False) -> float:
        """Reach, close the fingers (until each touches, then a little further), lift 8 cm or squeeze twice,
        release, retreat. A `miss` runs the same keyframes with the hand backed off along the palm normal until
        nothing of it comes within `CLEARANCE` of a surface (at least 1.5–4 cm): the fingers close in the air
        and a lifted hand leaves the object on the table (without room for that, the grasp itself)."""
        shape, track = self.objects[obj], self.script.tracks[hand]
        press = self.rng.uniform(0.002, 0.005)
        grip = self.top_grip if shape.kind == "sphere" else self.side_grip
        position, rotation = grip(hand, shape, press)
        flex = self.contact_flexion(hand, position, rotation, shape, self.rng.uniform(0.01, 0.04))
        if miss:
            squeezed = np.minimum(flex + 0.05, 1.0)
            positions = [position, position + [0, 0, 0.04], position + [0, 0, 0.08]] if lift else [position]
            gap = self.near_miss_gap(hand, positions, rotation, [OPEN_FLEX, flex, squeezed], -rotation[:, 2],
                                     self.rng.uniform(*MISS_GAP))
            miss = gap is not None
            position = position - (gap or 0.0) * rotation[:, 2]
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
            if not miss:
                self.attach(obj, hand, grab, t)
        if squeeze:
            for _ in range(2):
                t = track.add(t + 0.35, position, rotation, np.minimum(flex + 0.05, 1.0))
                t = track.add(t + 0.35, position, rotation, flex)
        t = track.hold(t + 0.4)
        t = track.add(t + 0.3, position, rotation, OPEN_FLEX)
        return self.label(start, self.retreat(hand, t), MISS if miss else GRASP if lift else SQUEEZE, (hand,))

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
        self.attach(obj, 1, t, t + 2.2)
        end = max(self.retreat(hand, t + 2.4) for hand in (0, 1))
        return self.label(start, end, CARRY, (0, 1))
