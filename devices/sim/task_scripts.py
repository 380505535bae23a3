"""Scripted tasks: reach → grasp (fingers close until they touch) → hold / lift / press / squeeze / slide /
rest / push → release → retreat, one- and two-handed, with idle stretches, and each action's near misses.
Produces keyframed hand tracks, object attachments (an object follows the hand that lifts or pushes it) and
labelled task segments."""
from __future__ import annotations

from touchanything.devices.sim.catalogue import (
    AIR_PUSH,
    CARRY,
    GRASP,
    HOLD_PRESS,
    HOVER,
    HOVER_PRESS,
    MISS,
    PRESS,
    PUSH,
    REST,
    REST_HOVER,
    SLIDE,
    SQUEEZE,
    UNTOUCHED,
)
from touchanything.devices.sim.grasp_actions import GraspActions
from touchanything.devices.sim.script_base import OPEN_FLEX
from touchanything.devices.sim.surface_actions import SurfaceActions, Where

NEAR_MISSES = {GRASP: (MISS,), SQUEEZE: (MISS,), PRESS: (HOVER, HOVER_PRESS), PUSH: (AIR_PUSH,), REST: (REST_HOVER,)}
"""The near-miss outcomes each action can be run as (see `catalogue.MISS`)."""


class Planner(GraspActions, SurfaceActions):
    """Builds a Script over the given objects (their poses change when an action moves them for good)."""

    def hold_and_press(self, t: float, obj: int) -> float:
        """The left hand steadies the object from its side while the right index presses its top."""
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
        return self.label(start, self.retreat(0, t), HOLD_PRESS, (0, 1))

    def run(self, action: str, t: float, where: Where, hand: int, variant: str | None = None) -> float:
        """Perform one action on object `where` (or, for press and rest, a table point), by `hand` for the
        one-handed actions, as `variant` (one of its `NEAR_MISSES`, or None for the action itself); returns
        its end time. A near miss whose hand would touch anything on the way (checked frame by frame) is
        replaced by the action itself."""
        for track in self.script.tracks:
            track.hold(t)
        if variant is None:
            return self._perform(action, t, where, hand, None)
        saved = self.snapshot()
        end = self._perform(action, t, where, hand, variant)
        segment = self.script.segments[-1]
        if segment.action in UNTOUCHED and self.touches(segment.hands[-1], segment.start, segment.end):
            self.restore(saved)
            end = self._perform(action, t, where, hand, None)
        return end

    def _perform(self, action: str, t: float, where: Where, hand: int, variant: str | None) -> float:
        if action in (GRASP, SQUEEZE):
            return self.grasp(hand, t, where, lift=action == GRASP, squeeze=action == SQUEEZE, miss=variant == MISS)
        if action == PRESS:
            return self.press(hand, t, where, variant or PRESS)
        if action == REST:
            return self.rest(hand, t, where, variant or REST)
        if action == PUSH:
            return self.push(hand, t, where, variant or PUSH)
        if action == SLIDE:
            return self.slide(hand, t, where)
        if action == CARRY:
            return self.carry(t, where)
        if action == HOLD_PRESS:
            return self.hold_and_press(t, where)
        raise ValueError(f"unknown action {action!r}")
