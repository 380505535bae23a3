"""Comparison frames (cameras on top; measured, predicted (an ensemble's: and its members' spread) and their
difference in the middle; metric and latency plots and the contact lamps at the bottom) and the video writer."""
from __future__ import annotations

from collections.abc import Collection
from pathlib import Path

import cv2
import numpy as np

from touchanything.core.output_safety import replacing
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.view_sets import view_label
from touchanything.devices.episodes.video_io import VideoWriter, video_comment
from touchanything.viz.pressure_panel import (
    BACKGROUND,
    MAP_TITLES,
    SPREAD_HIGH,
    SPREAD_TITLE,
    dimmed,
    layout_bend,
    pressure_panel,
    put_text,
)

WIDTH, CAMERA_HEIGHT, PANEL_HEIGHT, STRIP_HEIGHT, FOOTER_HEIGHT = 1440, 270, 360, 150, 26
CAPTION_COLOURS = ((235, 235, 235), (255, 180, 40))  # RGB: the model line, then a warning in amber
COMMENT = "touchanything comparison video"
"""The comment tag of every comparison video: what a later run may replace without --overwrite."""


def comparison_frame(images: dict[str, np.ndarray], gt: np.ndarray | None, pred: np.ndarray | None, footer: str,
                     strip: np.ndarray | None = None, hand3d: np.ndarray | None = None,
                     caption: tuple[str, ...] = (), used: Collection[str] = VIEW_NAMES,
                     spread: np.ndarray | None = None) -> np.ndarray:
    """(806, 1440, 3) uint8: the three views (480×270 each), the measured | predicted | difference maps, `strip`
    (150, 1440, 3) and the footer line; without a strip (656, 1440, 3). `hand3d` (h, 1440, 3), the pressure on
    the 3D hands, goes below the panels (the frame grows by h).

    `caption`: lines at the foot of the panels (what the model is; the second line, a warning, in amber).
    `used`: the views the model takes anything from (`view_sets.views_used`); the others are dimmed and labelled
    "… — not used". `spread` (an ensemble's, (2, 21, 21)): a fourth panel, the members' spread on [0, SPREAD_HIGH],
    right of the predicted maps (the four panels 360 wide). Absent views, ground truth or prediction leave
    labelled placeholders."""
    strip_height = 0 if strip is None else STRIP_HEIGHT
    extra = 0 if hand3d is None else hand3d.shape[0]
    frame = np.empty((CAMERA_HEIGHT + PANEL_HEIGHT + extra + strip_height + FOOTER_HEIGHT, WIDTH, 3), np.uint8)
    frame[:] = BACKGROUND
    for k, view in enumerate(VIEW_NAMES):
        x, label = k * 480, view_label(view, view in used)
        image = images.get(view)
        if image is not None:
            small = cv2.resize(image, (480, CAMERA_HEIGHT), interpolation=cv2.INTER_AREA)
            frame[:CAMERA_HEIGHT, x:x + 480] = small if view in used else dimmed(small)
        put_text(frame, label if image is not None or view not in used else f"{label}: no image", (x + 8, 22), 0.6)
    _draw_panels(frame, gt, pred, spread)
    top = CAMERA_HEIGHT + PANEL_HEIGHT
    for k, line in enumerate(reversed(caption)):
        put_text(frame, line, (10, top - 8 - 18 * k), 0.45, CAPTION_COLOURS[len(caption) - 1 - k])
    if hand3d is not None:
        frame[top:top + extra] = hand3d
    if strip is not None:
        frame[top + extra:top + extra + STRIP_HEIGHT] = strip
    put_text(frame, footer, (10, frame.shape[0] - 8), 0.5)
    return frame


def _draw_panels(frame: np.ndarray, gt: np.ndarray | None, pred: np.ndarray | None, spread: np.ndarray | None) -> None:
    """The map panels side by side under the cameras: measured | predicted [| spread] | difference, the bend
    cells of the pressure and difference panels drawn as such (`pressure_panel`)."""
    bend = layout_bend()
    panels = [(gt, MAP_TITLES["measured"], False, "no glove", 1.0, bend),
              (pred, MAP_TITLES["predicted"], False, "no pose", 1.0, bend)]
    panels += [(spread, SPREAD_TITLE, False, "no pose", SPREAD_HIGH, None)] if spread is not None else []
    panels += [(None if gt is None or pred is None else pred - gt, MAP_TITLES["error"], True, "n/a", 1.0, bend)]
    width = WIDTH // len(panels)
    for k, (grids, title, error, empty, high, hatched) in enumerate(panels):
        x = k * width
        if grids is None:
            put_text(frame, f"{title}: n/a", (x + 10, CAMERA_HEIGHT + 30), 0.6)
            continue
        frame[CAMERA_HEIGHT:CAMERA_HEIGHT + PANEL_HEIGHT, x:x + width] = pressure_panel(
            grids, title, width, PANEL_HEIGHT, error=error, empty=empty, high=high, bend=hatched)


def write_comparison_video(path: Path, frames) -> int:
    """Write an iterable of comparison frames as H.264 at 30 fps, tagged as a comparison video (so a later run
    may replace it without --overwrite), under the output rule (output_safety.replacing); returns the frame
    count."""
    with replacing(Path(path)) as temporary, VideoWriter(temporary, crf=23, metadata={"comment": COMMENT}) as writer:
        for frame in frames:
            writer.write(frame)
    return writer.frames_written


def is_comparison_video(path: Path) -> bool:
    """`path` is a comparison video this project wrote (its container's comment tag)."""
    return Path(path).suffix.lower() == ".mp4" and video_comment(path) == COMMENT
