"""The atlas panel: every setting of the speed/accuracy atlas (`touchanything bench`) as a dot — p99 per-frame
latency where the atlas was measured (log scale) against held-out volumetric IoU, one colour per model — and the
running setting as a ring at its p99 step time measured live (the engine's per-frame time over its recent
predictions) and its accuracy in the atlas. Switching model, runtime, views or rate moves the ring; a setting
the atlas does not hold is drawn as a dashed line at its live latency. The line under the plot follows the shown
prediction: without one on screen it gives no latency. Drawn as dearpygui geometry (no texture)."""
from __future__ import annotations

import math

import dearpygui.dearpygui as dpg

from touchanything.inference.evaluation.atlas import AtlasRow
from touchanything.viz.pressure_panel import AXES

MODEL_COLOURS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
                 (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))
"""matplotlib's tab10, the colours of the atlas's Pareto plot."""
RUNNING = (255, 255, 255)
TICKS_MS = (0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000)
LEGEND_WIDTH = 150


class AtlasPanel:
    """`width` × `height` pixels; the dots are drawn once (`show_atlas`), the ring on each `update`."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.left, self.right, self.top, self.bottom = 44, width - LEGEND_WIDTH - 8, 20, height - 32
        self.rows: tuple[AtlasRow, ...] = ()
        self.ring: tuple[float, float] | None = None
        """Where the running setting's ring is drawn (panel pixels), None when it is not."""
        self._span = (math.log10(0.5), math.log10(2000.0), 0.0, 1.0)
        with dpg.drawlist(width, height) as self.drawlist:
            dpg.draw_rectangle((self.left, self.top), (self.right, self.bottom), fill=AXES, color=AXES)
            self.title = dpg.draw_text((6, 2), "speed/accuracy atlas: no atlas", size=14)
            self.layer = dpg.add_draw_layer()
            self.marker = dpg.draw_circle((-20, -20), 7, color=RUNNING, thickness=2)
            self.line = dpg.draw_line((-20, -20), (-20, -20), color=RUNNING, thickness=1)
            self.caption = dpg.draw_text((6, height - 15), "", size=13)

    def x(self, p99_ms: float) -> float:
        low, high = self._span[:2]
        value = min(max(math.log10(max(p99_ms, 1e-3)), low), high)
        return self.left + (value - low) / (high - low) * (self.right - self.left)

    def y(self, viou: float) -> float:
        low, high = self._span[2:]
        return self.bottom - (min(max(viou, low), high) - low) / (high - low) * (self.bottom - self.top)

    def show_atlas(self, rows: tuple[AtlasRow, ...], note: str) -> None:
        """Draw the atlas's settings (once per atlas): axes spanning them, a dot per setting, the model legend."""
        self.rows = rows
        dpg.delete_item(self.layer, children_only=True)
        if not rows:
            dpg.configure_item(self.title, text=f"speed/accuracy atlas: {note or 'no atlas'}")
            return
        p99 = [r.atlas_p99_ms for r in rows]
        viou = [r.volumetric_iou for r in rows]
        pad = max(0.02, 0.08 * (max(viou) - min(viou)))
        self._span = (math.log10(min(p99)) - 0.25, math.log10(max(p99)) + 0.4, min(viou) - pad, max(viou) + pad)
        dpg.configure_item(self.title, text=f"speed/accuracy atlas: V-IoU (held-out, {rows[0].trajectories} "
                                            "trajectories) against p99 ms per frame")
        colours = {model: MODEL_COLOURS[i % len(MODEL_COLOURS)] for i, model in enumerate(dict.fromkeys(r.setting.model for r in rows))}
        for tick in TICKS_MS:
            if self._span[0] <= math.log10(tick) <= self._span[1]:
                dpg.draw_text((self.x(tick) - 6, self.bottom + 2), f"{tick:g}", size=11, parent=self.layer)
        for value in (self._span[2] + pad, self._span[3] - pad):
            dpg.draw_text((4, self.y(value) - 6), f"{value:.2f}", size=11, parent=self.layer)
        for row in rows:
            dpg.draw_circle((self.x(row.atlas_p99_ms), self.y(row.volumetric_iou)), 3, fill=colours[row.setting.model],
                            color=colours[row.setting.model], parent=self.layer)
        for i, (model, colour) in enumerate(colours.items()):
            y = self.top + 13 * i
            dpg.draw_circle((self.right + 14, y + 6), 4, fill=colour, color=colour, parent=self.layer)
            dpg.draw_text((self.right + 22, y), model, size=12, color=colour, parent=self.layer)

    def update(self, setting: str, p99_ms: float | None, timed: int, predicted: bool, accuracy: str) -> None:
        """Put the ring at the running `setting`'s live p99 (None: too few of its `timed` steps yet) and its atlas
        accuracy, while the shown record has a prediction (`predicted`; else no ring and no latency); `accuracy`:
        the running model's one accuracy as the line ends (`ModelAccuracy.caption`)."""
        row = next((r for r in self.rows if r.name == setting), None)
        p99_ms = p99_ms if predicted else None
        where = _latency_words(p99_ms, timed, predicted)
        if p99_ms is not None and self.rows and not self._span[0] <= math.log10(max(p99_ms, 1e-3)) <= self._span[1]:
            where += " (drawn at the edge of the scale)"
        if not self.rows or p99_ms is None:
            self._hide()
        elif row is None:
            self._hide()
            dpg.configure_item(self.line, p1=(self.x(p99_ms), self.top), p2=(self.x(p99_ms), self.bottom))
        else:
            dpg.configure_item(self.line, p1=(-20, -20), p2=(-20, -20))
            self.ring = (self.x(p99_ms), self.y(row.volumetric_iou))
            dpg.configure_item(self.marker, center=self.ring)
        dpg.configure_item(self.caption, text=f"running {setting}: {where}, {accuracy}" if setting else "")

    def _hide(self) -> None:
        self.ring = None
        dpg.configure_item(self.marker, center=(-20, -20))
        dpg.configure_item(self.line, p1=(-20, -20), p2=(-20, -20))


def _latency_words(p99_ms: float | None, timed: int, predicted: bool) -> str:
    """The caption's latency: the live p99, how many steps are timed so far, or that no prediction is shown."""
    if not predicted:
        return "no prediction on screen"
    if p99_ms is None:
        return f"{timed} prediction{'' if timed == 1 else 's'} timed, too few for a p99"
    return f"p99 {p99_ms:.1f} ms here"
