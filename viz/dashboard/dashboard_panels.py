"""The dashboard's images, built from a SessionState with the shared renderers (pure numpy/OpenCV)."""
from __future__ import annotations

import cv2
import numpy as np

from touchanything.devices.snapshot import Snapshot
from touchanything.viz.comparison_video import VIEW_LABELS
from touchanything.viz.dashboard.dashboard_state import SessionState
from touchanything.viz.hand_projection import draw_hands
from touchanything.viz.pressure_panel import BACKGROUND, pressure_maps, put_text, unposed_as_nan


def blank(width: int, height: int, text: str) -> np.ndarray:
    image = np.empty((height, width, 3), np.uint8)
    image[:] = BACKGROUND
    put_text(image, text, (10, 24), 0.55)
    return image


def camera_panel(snapshot: Snapshot | None, view: str, used: bool, width: int, height: int,
                 pressure: np.ndarray | None) -> np.ndarray:
    """One camera, downscaled to (height, width); the head camera carries the hand skeletons with the
    predicted pressure on their joints; a view the model does not use is dimmed and says so."""
    image = None if snapshot is None else snapshot.images.get(view)
    if image is None:
        return blank(width, height, f"{VIEW_LABELS[view]}: no image")
    small = cv2.resize(image, (width, height), interpolation=cv2.INTER_LINEAR)
    if view == "ego":
        small = draw_hands(small, snapshot.joints, snapshot.joints_valid, pressure)
    if not used:
        small = (small * 0.35).astype(np.uint8)
    put_text(small, VIEW_LABELS[view] + ("" if used else " - not used"), (6, 16), 0.4)
    return small


def pressure_views(state: SessionState, cell: int, threshold: float,
                   outline: bool) -> dict[str, tuple[np.ndarray | None, str]]:
    """name → (maps image or None when there is nothing to show, title) for the measured, predicted
    (optionally with the measured contact region outlined) and error maps."""
    prediction = state.prediction
    pred = None if prediction is None else prediction.pressure
    truth = state.truth
    measured = (pressure_maps(truth, cell, empty="no glove"), "Measured pressure") if truth is not None else \
        (None, "Measured pressure: n/a (no glove / ground truth)")
    if pred is None:
        predicted = (None, f"Predicted pressure: {'waiting for the model' if prediction is None else prediction.status}")
    else:
        pred = unposed_as_nan(pred, prediction.hands_predicted)
        missing = [side for side, ok in zip(("left", "right"), prediction.hands_predicted) if not ok]
        title = "Predicted pressure" + (" + measured contact" if outline and truth is not None else "")
        title += f" ({' and '.join(missing)}: no pose)" if missing else ""
        predicted = (pressure_maps(pred, cell, outline=truth if outline else None, threshold=threshold,
                                   empty="no pose"), title)
    error = (pressure_maps(pred - truth, cell, error=True), "Prediction - measured") \
        if pred is not None and truth is not None else (None, "Error: n/a")
    return {"measured": measured, "predicted": predicted, "error": error}
