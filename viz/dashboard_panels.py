"""The dashboard's images, built from a SessionState with the shared renderers (pure numpy/OpenCV)."""
from __future__ import annotations

import cv2
import numpy as np

from devices.snapshot import Snapshot
from viz.comparison_video import VIEW_LABELS
from viz.contact import contact_badges, hand_contact
from viz.hand_projection import draw_hands
from viz.line_plot import line_plot
from viz.pressure_panel import BACKGROUND, pressure_panel, put_text
from viz.dashboard_state import SessionState

LATENCY_PLOT_MS = 200.0


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
    small = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    if view == "ego":
        small = draw_hands(small, snapshot.joints, snapshot.joints_valid, pressure)
    if not used:
        small = (small * 0.35).astype(np.uint8)
    put_text(small, VIEW_LABELS[view] + ("" if used else " - not used by the model"), (8, 20), 0.5)
    return small


def pressure_panels(state: SessionState, width: int, height: int, threshold: float,
                    outline: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Measured, predicted (optionally with the measured contact region outlined) and error panels."""
    prediction = state.prediction
    pred = None if prediction is None else prediction.pressure
    truth = state.truth
    measured = pressure_panel(truth, "Measured Pressure", width, height) if truth is not None else \
        blank(width, height, "Measured Pressure: n/a (no glove / ground truth)")
    if pred is None:
        reason = "waiting for the model" if prediction is None else prediction.status
        predicted = blank(width, height, f"Predicted Pressure: {reason}")
    else:
        labels = tuple(f"{side} Hand" + ("" if ok else " (no pose)")
                       for side, ok in zip(("Left", "Right"), prediction.hands_predicted))
        predicted = pressure_panel(pred, "Predicted" + (" + measured contact" if outline and truth is not None else ""),
                                   width, height, labels=labels, outline=truth if outline else None, threshold=threshold)
    error = pressure_panel(pred - truth, "Prediction - Measured", width, height, error=True) \
        if pred is not None and truth is not None else blank(width, height, "Error: n/a")
    return measured, predicted, error


def plots_panel(state: SessionState, width: int, height: int, capacity: int) -> np.ndarray:
    """Rolling metrics (3 s window) above engine latency."""
    top = height // 2
    history = state.history
    panel = np.empty((height, width, 3), np.uint8)
    metrics = {"V-IoU": history.get("volumetric_iou", np.zeros(0)), "C-IoU": history.get("contact_iou", np.zeros(0))}
    title = "metrics, rolling 3 s" if state.rolling is not None else "metrics: n/a (no ground truth)"
    panel[:top] = line_plot(metrics, width, top, 1.0, title, capacity)
    panel[top:] = line_plot({"latency": history.get("latency_ms", np.zeros(0))}, width, height - top,
                            LATENCY_PLOT_MS, "capture to prediction", capacity, " ms")
    return panel


def contact_panel(state: SessionState, bend: np.ndarray, threshold: float, width: int, height: int) -> np.ndarray:
    prediction = state.prediction
    pred = None if prediction is None else prediction.pressure
    return contact_badges(hand_contact(pred, bend, threshold), hand_contact(state.truth, bend, threshold), width, height)
