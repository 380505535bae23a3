"""The dashboard's images, built from a SessionState with the shared renderers (pure numpy/OpenCV)."""
from __future__ import annotations

import cv2
import numpy as np

from touchanything.core.snapshot import HANDS, Snapshot
from touchanything.core.view_sets import view_label
from touchanything.inference.engine.prediction import Prediction
from touchanything.viz.dashboard.dashboard_state import SessionState
from touchanything.viz.frame_facts import FrameFacts
from touchanything.viz.hand_projection import draw_hands
from touchanything.viz.pressure_panel import (
    BACKGROUND,
    MAP_TITLES,
    SPREAD_HIGH,
    SPREAD_TITLE,
    dimmed,
    layout_bend,
    pressure_maps,
    put_text,
    unposed_as_nan,
)

SPREAD_MAP_TITLE = f"{SPREAD_TITLE} (0–{SPREAD_HIGH:g})"
"""The predicted map's title while it shows the members' spread: what it is and its scale."""


def blank(width: int, height: int, text: str) -> np.ndarray:
    image = np.empty((height, width, 3), np.uint8)
    image[:] = BACKGROUND
    put_text(image, text, (10, 24), 0.55)
    return image


def camera_panel(snapshot: Snapshot | None, view: str, used: bool, width: int, height: int,
                 pressure: np.ndarray | None) -> np.ndarray:
    """One camera, downscaled to (height, width); the head camera carries the hand skeletons with the
    predicted pressure on their joints; a view the model does not use (`used` False) is dimmed and labelled
    "… — not used" (`view_label`)."""
    image = None if snapshot is None else snapshot.images.get(view)
    if image is None:
        panel = blank(width, height, view_label(view, used))
        put_text(panel, "no image", (10, 44), 0.55)
        return panel
    small = cv2.resize(image, (width, height), interpolation=cv2.INTER_LINEAR)
    if view == "ego":
        small = draw_hands(small, snapshot.joints, snapshot.joints_valid, pressure)
    if not used:
        small = dimmed(small)
    put_text(small, view_label(view, used), (6, 16), 0.4)
    return small


def pressure_views(state: SessionState, cell: int, threshold: float, outline: bool,
                   spread: bool = False) -> dict[str, tuple[np.ndarray | None, str]]:
    """name → (maps image or None when there is nothing to show, title) for the measured, predicted
    (optionally with the measured contact region outlined) and error maps; with `spread` and an ensemble running
    (`state.members` > 1) the predicted map shows the prediction's members' spread instead, on the spread's scale
    (`SPREAD_MAP_TITLE`, no outline). Which hand each map shows, and each title's "no pose" / "no glove", come
    from the prediction's facts (`state.facts`): map and title agree. Bend cells are drawn as such in the
    pressure and error maps (`pressure_panel`); the outline is of the measured tactile cells only."""
    prediction, truth, facts = state.prediction, state.truth, state.facts
    titles = dict(MAP_TITLES)
    if truth is None:
        measured = (None, f"{titles['measured']}: n/a (no glove / ground truth)")
    else:
        gloveless = [name for name, hand in zip(HANDS, facts.hands) if not hand.measured] if facts is not None else []
        measured = (pressure_maps(truth, cell, empty="no glove", bend=layout_bend()), titles["measured"] + _without(gloveless, "no glove"))
    shows_spread = spread and state.members > 1
    pred = None
    if prediction is None or prediction.pressure is None or facts is None:
        why = "waiting for the model" if prediction is None or facts is None else prediction.status
        predicted = (None, f"{SPREAD_MAP_TITLE if shows_spread else titles['predicted']}: {why}")
    else:
        pred = unposed_as_nan(prediction.pressure, facts.posed)
        title = titles["predicted"] + (" + measured contact" if outline and truth is not None else "")
        predicted = spread_view(prediction, facts, cell) if shows_spread else \
            (pressure_maps(pred, cell, outline=truth if outline else None, threshold=threshold, empty="no pose",
                           bend=layout_bend()),
             title + _without(facts.unposed, "no pose"))
    error = (pressure_maps(pred - truth, cell, error=True, bend=layout_bend()), titles["error"]) if pred is not None and truth is not None \
        else (None, f"{titles['error']}: n/a")
    return {"measured": measured, "predicted": predicted, "error": error}


def spread_view(prediction: Prediction, facts: FrameFacts, cell: int) -> tuple[np.ndarray | None, str]:
    """(maps image, title) of the prediction's members' spread on [0, SPREAD_HIGH], its hands as `facts` say
    (an unposed hand reads "no pose"); (None, why) for a prediction without a spread (a single model's)."""
    if prediction.spread is None:
        return None, f"{SPREAD_MAP_TITLE}: n/a (one model)"
    maps = pressure_maps(unposed_as_nan(prediction.spread, facts.posed), cell, empty="no pose", high=SPREAD_HIGH)
    return maps, SPREAD_MAP_TITLE + _without(facts.unposed, "no pose")


def _without(hands: list[str], why: str) -> str:
    """" (no pose: left, right)" for the hands a map leaves out; "" for none."""
    return f" ({why}: {', '.join(hands)})" if hands else ""
