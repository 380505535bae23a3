"""Object catalogue (stable ids) and the five scene categories of the simulated world."""
from __future__ import annotations

from dataclasses import dataclass

from touchanything.devices.sim.renderer import Lighting


@dataclass(frozen=True)
class ObjectSpec:
    """kind/size as in `Shape` (before the episode's size scale); actions this object affords; softness as in
    `Shape` (0 = rigid)."""

    id: str
    kind: str
    size: tuple[float, ...]
    colour: tuple[int, int, int]
    actions: tuple[str, ...]
    pattern: str = "plain"
    accent: tuple[int, int, int] = (255, 255, 255)
    softness: float = 0.0


GRASP, PRESS, SQUEEZE, SLIDE, CARRY, HOLD_PRESS = "hold", "press", "squeeze", "slide", "carry", "hold_and_press"
PUSH, REST = "push", "rest"
BIMANUAL_ACTIONS = (CARRY, HOLD_PRESS)
MISS, HOVER, HOVER_PRESS, AIR_PUSH, REST_HOVER = "miss", "hover", "hover_press", "air_push", "rest_hover"
"""Near-miss outcomes (task labels): the same motion as an action, a few centimetres short of the surface, or a
hover before the touch. `miss`: a hold or squeeze closing in the air; `hover`: a pointing finger stops 1–3 cm
above a surface and withdraws; `hover_press`: it hovers, then presses; `air_push`: a push that misses the
object; `rest_hover`: a flat hand held just above a surface instead of resting on it."""
UNTOUCHED = (MISS, HOVER, AIR_PUSH, REST_HOVER)
"""The outcomes in which the hand touches nothing."""
SIZE_SCALE = (0.85, 1.2)
"""Each episode scales each object's size by a factor drawn from this range (heights and widths vary)."""

CATALOGUE = {o.id: o for o in (
    ObjectSpec("mug_red", "cylinder", (0.040, 0.050), (190, 40, 35), (GRASP, SQUEEZE, HOLD_PRESS, PUSH)),
    ObjectSpec("mug_black", "cylinder", (0.040, 0.050), (38, 38, 42), (GRASP, SQUEEZE, HOLD_PRESS, PUSH)),
    ObjectSpec("bottle_green", "cylinder", (0.034, 0.110), (40, 150, 70), (GRASP, SQUEEZE), "stripes", (230, 230, 210)),
    ObjectSpec("bottle_dark", "cylinder", (0.034, 0.110), (30, 32, 40), (GRASP, SQUEEZE)),
    ObjectSpec("can_silver", "cylinder", (0.033, 0.060), (185, 188, 195), (GRASP, SQUEEZE, PRESS, PUSH), "stripes", (200, 40, 40)),
    ObjectSpec("jar_blue", "cylinder", (0.045, 0.060), (70, 120, 200), (GRASP, SQUEEZE, HOLD_PRESS, PUSH, REST)),
    ObjectSpec("ball_orange", "sphere", (0.050,), (235, 130, 30), (GRASP, SQUEEZE)),
    ObjectSpec("ball_black", "sphere", (0.050,), (35, 35, 38), (GRASP, SQUEEZE)),
    ObjectSpec("ball_green", "sphere", (0.045,), (90, 190, 60), (GRASP, SQUEEZE)),
    ObjectSpec("box_cardboard", "box", (0.090, 0.070, 0.065), (175, 135, 90), (CARRY, PRESS, SLIDE, HOLD_PRESS, PUSH, REST),
               "checker", (160, 120, 80)),
    ObjectSpec("box_blue", "box", (0.085, 0.065, 0.060), (50, 80, 170), (CARRY, PRESS, SLIDE, PUSH, REST), "stripes", (230, 230, 240)),
    ObjectSpec("box_dark", "box", (0.080, 0.065, 0.060), (36, 36, 40), (CARRY, PRESS, SLIDE, HOLD_PRESS, PUSH, REST)),
    ObjectSpec("block_wood", "box", (0.035, 0.035, 0.045), (160, 110, 60), (GRASP, PRESS, SQUEEZE, PUSH), "stripes", (140, 95, 50)),
    ObjectSpec("panel_grey", "box", (0.110, 0.080, 0.012), (150, 150, 155), (PRESS, SLIDE, REST), "checker", (120, 120, 125)),
    ObjectSpec("panel_white", "box", (0.120, 0.085, 0.010), (225, 225, 220), (PRESS, SLIDE, REST)),
    ObjectSpec("button_box_yellow", "box", (0.060, 0.050, 0.030), (230, 200, 40), (PRESS, HOLD_PRESS, PUSH, REST), "checker", (40, 40, 40)),
    ObjectSpec("tablet_black", "box", (0.100, 0.070, 0.006), (30, 30, 34), (PRESS, SLIDE)),
    ObjectSpec("crate_green", "box", (0.095, 0.075, 0.070), (60, 130, 70), (CARRY, PRESS, SLIDE, PUSH, REST), "stripes", (40, 90, 50)),
    ObjectSpec("sponge_yellow", "box", (0.055, 0.038, 0.024), (235, 200, 50), (PRESS, SLIDE, REST), "stripes", (70, 150, 70), 0.8),
    ObjectSpec("foam_pink", "box", (0.048, 0.048, 0.032), (230, 130, 170), (PRESS, REST), "checker", (245, 170, 200), 0.75),
    ObjectSpec("cushion_blue", "box", (0.075, 0.058, 0.028), (120, 170, 225), (PRESS, SLIDE, REST), "checker", (95, 140, 200), 0.85),
)}

UNSEEN_OBJECTS = frozenset({"mug_black", "ball_green", "box_blue", "panel_white", "bottle_dark"})
"""Held out of training: episodes with these objects form `test_unseen`."""


@dataclass(frozen=True)
class SceneCategory:
    name: str
    table: tuple[int, int, int]
    table_accent: tuple[int, int, int]
    wall: tuple[int, int, int]
    lighting: Lighting
    objects: tuple[str, ...]


SCENES = {s.name: s for s in (
    SceneCategory("Home", (170, 125, 80), (150, 105, 65), (215, 205, 185),
                  Lighting((0.3, 0.4, -0.85), 0.45, (235, 225, 205), (150, 140, 120), 1.0),
                  ("mug_red", "mug_black", "bottle_green", "jar_blue", "ball_orange", "box_cardboard", "tablet_black", "sponge_yellow")),
    SceneCategory("Workbench", (120, 120, 125), (95, 95, 100), (170, 175, 180),
                  Lighting((-0.4, 0.3, -0.85), 0.35, (200, 205, 210), (90, 95, 100), 1.05),
                  ("block_wood", "box_dark", "can_silver", "crate_green", "button_box_yellow", "bottle_dark", "foam_pink")),
    SceneCategory("Office", (225, 225, 228), (205, 205, 210), (190, 200, 215),
                  Lighting((0.1, 0.6, -0.8), 0.55, (230, 235, 245), (170, 175, 190), 0.95),
                  ("panel_grey", "panel_white", "button_box_yellow", "mug_red", "tablet_black", "box_blue", "cushion_blue")),
    SceneCategory("Retail", (200, 185, 150), (185, 170, 135), (235, 235, 235),
                  Lighting((0.0, 0.2, -1.0), 0.6, (250, 250, 250), (200, 200, 200), 1.0),
                  ("box_cardboard", "box_blue", "crate_green", "bottle_green", "can_silver", "jar_blue", "sponge_yellow")),
    SceneCategory("Outdoor", (90, 130, 60), (75, 115, 50), (150, 190, 230),
                  Lighting((0.5, 0.2, -0.85), 0.3, (150, 195, 240), (120, 150, 110), 1.15),
                  ("ball_orange", "ball_black", "ball_green", "box_dark", "crate_green", "block_wood", "foam_pink")),
)}
