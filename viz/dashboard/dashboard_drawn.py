"""Dashboard widgets drawn as dearpygui geometry instead of textures (dearpygui re-uploads every texture
every frame): the contact lamps and the history plots. They show what the exporter's `contact_badges`
and `line_plot` images show, with the same colours, on the window's own background (under software
OpenGL every covered pixel costs, about 20 ns of CPU per frame)."""
from __future__ import annotations

import dearpygui.dearpygui as dpg
import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.viz.contact import UNKNOWN, lamp_colour, verdict
from touchanything.viz.frame_facts import FrameFacts, Metrics
from touchanything.viz.line_plot import LATENCY_PLOT_MS, PLOT_SAMPLES, SERIES_COLOURS
from touchanything.viz.pressure_panel import AXES


class ContactLamps:
    """Per hand: the predicted and the measured contact lamp and whether they agree."""

    def __init__(self, width: int, height: int) -> None:
        row = height // 3
        with dpg.drawlist(width, height):
            dpg.draw_text((8, 4), "contact", size=15)
            dpg.draw_text((width // 3, 4), "pred", size=14)
            dpg.draw_text((2 * width // 3 - 10, 4), "meas", size=14)
            self.lamps, self.verdicts = [], []
            for h, label in enumerate(HANDS):
                y = row * (h + 1) + row // 2
                dpg.draw_text((8, y - 8), label, size=15)
                self.lamps.append([dpg.draw_circle((width // 3 + 14 + k * (width // 3 - 10), y), row // 3,
                                                   fill=UNKNOWN, color=(0, 0, 0)) for k in range(2)])
                self.verdicts.append(dpg.draw_text((width - 46, y - 8), "", size=14))

    def update(self, facts: FrameFacts | None) -> None:
        """Show `facts` (None: nothing known yet)."""
        for h in range(2):
            hand = None if facts is None else facts.hands[h]
            for k in range(2):
                contact = None if hand is None else (hand.contact_predicted, hand.contact_measured)[k]
                dpg.configure_item(self.lamps[h][k], fill=lamp_colour(contact))
            word, colour = verdict(None if hand is None else hand.agree)
            dpg.configure_item(self.verdicts[h], text=word, color=colour)


class HistoryPlots:
    """Two stacked line plots, newest sample at the right: rolling V-IoU and C-IoU on [0, 1] above the
    capture-to-prediction latency on [0, LATENCY_PLOT_MS]; undefined samples leave gaps. The legends carry
    the shown prediction's values (`show_values`: the same record the metrics table reads), the lines the
    recent history (`update`)."""

    PANES = ((("volumetric_iou", "V-IoU"), ("contact_iou", "C-IoU")), (("latency_ms", "latency"),))

    def __init__(self, width: int, height: int) -> None:
        self.width, self.pane = width, height // 2
        self.lines: dict[str, int] = {}
        self.legends: dict[str, int] = {}
        with dpg.drawlist(width, height):
            for p, (series, title) in enumerate(zip(self.PANES, ("metrics, rolling 3 s", "capture to prediction"))):
                top = p * self.pane
                dpg.draw_rectangle((34, top + 22), (width - 6, top + self.pane - 8), fill=AXES, color=AXES)
                dpg.draw_text((6, top + 2), title, size=14)
                dpg.draw_text((4, top + 20), "1" if p == 0 else f"{LATENCY_PLOT_MS:g}", size=12)
                dpg.draw_text((20, top + self.pane - 20), "0", size=12)
                for k, (key, label) in enumerate(series):
                    colour = SERIES_COLOURS[k]
                    self.lines[key] = dpg.draw_polyline([], color=colour, thickness=1)
                    self.legends[key] = dpg.draw_text((40 + 95 * k, top + 24), f"{label} n/a", color=colour, size=14)

    def update(self, history: dict[str, np.ndarray]) -> None:
        """The lines: each series' last PLOT_SAMPLES values."""
        for p, series in enumerate(self.PANES):
            top, scale = p * self.pane, 1.0 if p == 0 else LATENCY_PLOT_MS
            for key, _ in series:
                values = history.get(key, np.zeros(0))[-PLOT_SAMPLES:]
                x = self.width - 6 - (len(values) - 1 - np.arange(len(values))) * (self.width - 40) / (PLOT_SAMPLES - 1)
                y = top + self.pane - 8 - np.clip(values, 0, scale) / scale * (self.pane - 30)
                finite = np.isfinite(values)
                dpg.configure_item(self.lines[key], points=np.stack([x[finite], y[finite]], axis=1).tolist())

    def show_values(self, rolling: Metrics | None, latency_ms: float | None) -> None:
        """The legends: the rolling metrics of the shown prediction's facts (two decimals; "n/a" for None) and
        its latency."""
        values = {**(rolling or {}), "latency_ms": latency_ms}
        for series in self.PANES:
            for key, label in series:
                value = values.get(key)
                text = "n/a" if value is None else f"{value:.0f} ms" if key == "latency_ms" else f"{value:.2f}"
                dpg.configure_item(self.legends[key], text=f"{label} {text}")
