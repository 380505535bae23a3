"""Dashboard widgets drawn as dearpygui geometry instead of textures (dearpygui re-uploads every texture
every frame): the contact lamps and the history plots. They show what the exporter's `contact_badges`
and `line_plot` images show, with the same colours, on the window's own background (under software
OpenGL every covered pixel costs, about 20 ns of CPU per frame)."""
from __future__ import annotations

import dearpygui.dearpygui as dpg
import numpy as np

from touchanything.viz.contact import OFF, ON, UNKNOWN
from touchanything.viz.line_plot import LATENCY_PLOT_MS, PLOT_SAMPLES, SERIES_COLOURS
from touchanything.viz.pressure_panel import AXES

AGREE, DISAGREE = (160, 230, 160), (255, 140, 120)


class ContactLamps:
    """Per hand: the predicted and the measured contact lamp and whether they agree."""

    def __init__(self, width: int, height: int) -> None:
        row = height // 3
        with dpg.drawlist(width, height):
            dpg.draw_text((8, 4), "contact", size=15)
            dpg.draw_text((width // 3, 4), "pred", size=14)
            dpg.draw_text((2 * width // 3 - 10, 4), "meas", size=14)
            self.lamps, self.verdicts = [], []
            for h, label in enumerate(("left", "right")):
                y = row * (h + 1) + row // 2
                dpg.draw_text((8, y - 8), label, size=15)
                self.lamps.append([dpg.draw_circle((width // 3 + 14 + k * (width // 3 - 10), y), row // 3,
                                                   fill=UNKNOWN, color=(0, 0, 0)) for k in range(2)])
                self.verdicts.append(dpg.draw_text((width - 46, y - 8), "", size=14))

    def update(self, predicted: np.ndarray | None, measured: np.ndarray | None) -> None:
        for h in range(2):
            for k, flags in enumerate((predicted, measured)):
                dpg.configure_item(self.lamps[h][k], fill=UNKNOWN if flags is None else (ON if flags[h] else OFF))
            known = predicted is not None and measured is not None
            agree = known and predicted[h] == measured[h]
            dpg.configure_item(self.verdicts[h], text=("ok" if agree else "miss") if known else "",
                               color=AGREE if agree else DISAGREE)


class HistoryPlots:
    """Two stacked line plots, newest sample at the right: rolling V-IoU and C-IoU on [0, 1] above the
    capture-to-prediction latency on [0, LATENCY_PLOT_MS]; undefined samples leave gaps."""

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
                for k, (key, _) in enumerate(series):
                    colour = SERIES_COLOURS[k]
                    self.lines[key] = dpg.draw_polyline([], color=colour, thickness=1)
                    self.legends[key] = dpg.draw_text((40 + 95 * k, top + 24), "", color=colour, size=14)

    def update(self, history: dict[str, np.ndarray]) -> None:
        for p, series in enumerate(self.PANES):
            top, scale = p * self.pane, 1.0 if p == 0 else LATENCY_PLOT_MS
            for key, label in series:
                values = history.get(key, np.zeros(0))[-PLOT_SAMPLES:]
                x = self.width - 6 - (len(values) - 1 - np.arange(len(values))) * (self.width - 40) / (PLOT_SAMPLES - 1)
                y = top + self.pane - 8 - np.clip(values, 0, scale) / scale * (self.pane - 30)
                finite = np.isfinite(values)
                dpg.configure_item(self.lines[key], points=np.stack([x[finite], y[finite]], axis=1).tolist())
                latest = values[finite][-1] if finite.any() else None
                text = "n/a" if latest is None else (f"{latest:.0f} ms" if p else f"{latest:.2f}")
                dpg.configure_item(self.legends[key], text=f"{label} {text}")
