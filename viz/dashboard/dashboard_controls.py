"""The dashboard's right-hand column: controls wired to the session, and the metric, timing and device
tables refreshed from each SessionState."""
from __future__ import annotations

from pathlib import Path
from typing import Protocol

import dearpygui.dearpygui as dpg
import numpy as np

from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.core.view_sets import VIEW_LABELS
from touchanything.devices.camera_pose.estimator import STAGE as POSE_STAGE
from touchanything.viz.dashboard.dashboard_state import DashboardSession, SessionState, SourceStatus
from touchanything.viz.frame_facts import FrameFacts, metric_text
from touchanything.viz.hand_projection import pose_label

SPEEDS = ("0.25", "0.5", "1", "2", "4")
RATES = ("1", "2", "3")
"""Predict every k-th frame (the atlas's prediction rates)."""
METRIC_ROWS = (("temporal_accuracy", "temporal accuracy"), ("contact_iou", "contact IoU"),
               ("volumetric_iou", "volumetric IoU"), ("mae", "MAE"))
STAGES = ((POSE_STAGE, "pose"), ("preprocess", "preprocess"), ("encode", "encode"), ("head", "head"),
          ("total", "total"))
"""(stage, column title): the hand-pose estimator (camera poses only) and the engine's stages."""
DEVICE_ROWS = 10
DEVICE_COLUMNS = (("source", 18), ("state", 24), ("rate", 6), ("age", 8), ("drops", 5))
"""Device table columns and their widths in characters: a longer text is cut with "…" (the state's full
text is in its tooltip), so that no text runs into the next column. A camera's row is named by its label."""
TEXT_WIDTH = 455
"""Pixels from a text's start to where it wraps: the right-hand column's width (beside a scroll bar too)."""
HEADER_HEIGHT = 104
"""Pixels of the header (the model's line, the pose, the recording and the message): room for seven lines of
text with the gaps between them (the model's line takes two, the message up to three). Its height is fixed, so
that no text moves the controls below it; what does not fit scrolls inside it."""


class ControlledDashboard(Protocol):
    """What the controls use of the dashboard (`Dashboard` satisfies it; the dashboard imports this module,
    never the other way round)."""

    session: DashboardSession
    outline: bool
    note: str

    def request_screenshot(self, path: Path | None = None) -> None: ...


def build_controls(dash: ControlledDashboard) -> None:
    """The header (a fixed height) and the controls below it."""
    session = dash.session
    with dpg.child_window(tag="header", height=HEADER_HEIGHT, border=False):
        for tag in ("model_text", "pose_text", "recording_text", "message_text"):
            dpg.add_text("", tag=tag, wrap=TEXT_WIDTH)
    with dpg.group(tag="transport"):
        with dpg.group(horizontal=True):
            dpg.add_button(label="Pause", tag="play_button", width=70, callback=lambda: _play_pause(dash))
            dpg.add_button(label="Step", width=60, callback=lambda: session.step())
            dpg.add_text("speed")
            dpg.add_combo(SPEEDS, default_value="1", width=70, tag="speed",
                          callback=lambda s, value: session.set_speed(float(value)))
        with dpg.group(horizontal=True):
            dpg.add_slider_int(tag="seek", format="", min_value=0, max_value=1, width=330,
                               callback=lambda s, value: session.seek(int(value)))
            dpg.add_text("", tag="frame_text")
    with dpg.group(horizontal=True):
        dpg.add_text("views")
        for view in VIEW_NAMES:
            dpg.add_checkbox(label=VIEW_LABELS[view], tag=f"view_{view}", default_value=view in session.views,
                             callback=lambda: _set_views(dash))
    model, tier = session.current_model()
    with dpg.group(horizontal=True):
        dpg.add_text("model")
        dpg.add_combo(session.models(), default_value=model, tag="model", width=150, callback=lambda: _set_model(dash))
        dpg.add_combo(session.tiers(), default_value=tier, tag="tier", width=120, callback=lambda: _set_model(dash))
        dpg.add_text("every")
        dpg.add_combo(RATES, default_value=str(session.current_rate()), tag="rate", width=45,
                      callback=lambda s, value: dash.session.set_rate(int(value)))
    with dpg.group(horizontal=True):
        dpg.add_slider_float(label="contact threshold", tag="threshold", default_value=session.threshold,
                             min_value=0.02, max_value=0.5, width=140, format="%.2f",
                             callback=lambda s, value: _set_threshold(dash, value))
        dpg.add_checkbox(label="outline measured", callback=lambda s, value: setattr(dash, "outline", value))
    with dpg.group(horizontal=True):
        dpg.add_button(label="Record", tag="record_button", width=110, callback=lambda: _record(dash))
        dpg.add_button(label="Screenshot", tag="screenshot_button", width=110, callback=lambda: dash.request_screenshot())


def _record(dash: ControlledDashboard) -> None:
    """The Record button: its answer (the session's message) replaces whatever the dashboard said last."""
    dash.note = ""
    dash.session.toggle_recording()


def _play_pause(dash: ControlledDashboard) -> None:
    playback = dash.session.state().playback
    if playback is not None and playback.paused:
        dash.session.play()
    else:
        dash.session.pause()


def _set_views(dash: ControlledDashboard) -> None:
    dash.session.set_views(tuple(v for v in VIEW_NAMES if dpg.get_value(f"view_{v}")))


def _set_model(dash: ControlledDashboard) -> None:
    dash.session.set_model(dpg.get_value("model"), dpg.get_value("tier"))


def _set_threshold(dash: ControlledDashboard, value: float) -> None:
    try:
        dash.session.set_threshold(float(value))
        dash.note = ""
    except UserError as exc:
        dash.note = str(exc)


def build_tables(char_width: float) -> None:
    """The metric, stage and device tables; `char_width`: the monospaced font's advance in pixels."""
    with dpg.table(header_row=True, tag="metrics_table", borders_innerH=True):
        for title in ("official metric", "rolling 3 s", "cumulative"):
            dpg.add_table_column(label=title)
        for key, label in METRIC_ROWS:
            with dpg.table_row():
                dpg.add_text(label)
                dpg.add_text("n/a", tag=f"rolling_{key}")
                dpg.add_text("n/a", tag=f"cumulative_{key}")
    dpg.add_text("", tag="performance_text", wrap=460)
    with dpg.table(header_row=True, tag="stage_table"):
        dpg.add_table_column(label="ms")
        for _, title in STAGES:
            dpg.add_table_column(label=title)
        with dpg.table_row():
            dpg.add_text("mean of 30")
            for stage, _ in STAGES:
                dpg.add_text("-", tag=f"stage_{stage}")
    with dpg.table(header_row=True, tag="device_table", policy=dpg.mvTable_SizingFixedFit):
        for title, chars in DEVICE_COLUMNS:
            dpg.add_table_column(label=title, init_width_or_weight=round(chars * char_width), width_fixed=True)
        for row in range(DEVICE_ROWS):
            with dpg.table_row(tag=f"device_row_{row}"):
                for column in range(len(DEVICE_COLUMNS)):
                    dpg.add_text("", tag=f"device_{row}_{column}")
            with dpg.tooltip(f"device_{row}_1"):
                dpg.add_text("", tag=f"device_{row}_full", wrap=500)


class Tables:
    """The texts and tables, refreshed from each SessionState; an item is touched only when its content
    changes."""

    def __init__(self) -> None:
        self._shown: dict[tuple[str, str], object] = {}
        self._seen = ("", "")
        self._message = ""

    def _put(self, tag: str, key: str, value: object) -> bool:
        """Set `key` ("value" or a configuration option) of item `tag` unless it already holds `value`."""
        if self._shown.get((tag, key), ...) == value:
            return False
        self._shown[(tag, key)] = value
        if key == "value":
            dpg.set_value(tag, value)
        else:
            dpg.configure_item(tag, **{key: value})
        return True

    def message(self, note: str, message: str) -> str:
        """The one message line: the newest of the dashboard's own `note` and the session's `message` (a note
        cleared gives the line back to the session's message)."""
        if message != self._seen[1]:
            self._message = message
        if note != self._seen[0]:
            self._message = note or message
        self._seen = (note, message)
        return self._message

    def show_metrics(self, facts: FrameFacts | None) -> None:
        """The metric table from the shown prediction's facts (with the maps, the lamps and the plots' legends,
        never on its own clock)."""
        for key, _ in METRIC_ROWS:
            for column, values in (("rolling", facts and facts.rolling), ("cumulative", facts and facts.cumulative)):
                self._put(f"{column}_{key}", "value", metric_text(None if values is None else values[key]))

    def show_pose(self, snapshot: Snapshot | None) -> None:
        """The pose line of the shown snapshot (with its camera images, never on the tables' clock)."""
        self._put("pose_text", "value", pose_label(snapshot))

    def update(self, state: SessionState, note: str, display_fps: float) -> None:
        """Refresh from `state`; `note`: the dashboard's own notice (`message`)."""
        texts = {("model_text", "value"): f"model: {state.model}",
                 ("message_text", "value"): self.message(note, state.message),
                 ("record_button", "label"): "Stop recording" if state.recording else "Record",
                 ("recording_text", "value"): state.recording or "", ("recording_text", "show"): bool(state.recording),
                 ("transport", "show"): state.playback is not None,
                 ("performance_text", "value"): _performance_line(state, display_fps)}
        playback = state.playback
        if playback is not None:
            texts[("play_button", "label")] = "Play" if playback.paused else "Pause"
            texts[("seek", "max_value")] = max(playback.frames - 1, 1)
            shown = _shown_frame(state)
            texts[("frame_text", "value")] = f"frame {shown} of {playback.frames}"
            if not dpg.is_item_active("seek"):
                texts[("seek", "value")] = shown
        for stage, _ in STAGES:
            texts[(f"stage_{stage}", "value")] = _stage_text(state, stage)
        rows = state.sources[:DEVICE_ROWS]
        for row in range(DEVICE_ROWS):
            texts[(f"device_row_{row}", "show")] = row < len(rows)
            if row < len(rows):
                for column, text in enumerate(_device_cells(rows[row])):
                    texts[(f"device_{row}_{column}", "value")] = text
                texts[(f"device_{row}_full", "value")] = rows[row].detail or \
                    ("no details" if rows[row].in_scene else "the scene has no such source")
        for (tag, key), value in texts.items():
            self._put(tag, key, value)


def _shown_frame(state: SessionState) -> int:
    """The frame on screen (the slider shows it, not the next one to play): the snapshot's, or before the
    first one, the playback position."""
    playback = state.playback
    frame = state.snapshot.frame_index if state.snapshot is not None else playback.position
    return min(frame, playback.frames - 1)


def _on_screen(state: SessionState) -> bool:
    """Whether the shown record has a prediction (what the engine's times and latency describe)."""
    return state.facts is not None and state.facts.predicted


def _stage_text(state: SessionState, stage: str) -> str:
    """A stage's mean time: the pose's ("-" when not estimated), the engine's ("n/a" without a prediction on
    screen, "skipped" when the stage did not run)."""
    value = state.stage_ms.get(stage)
    if stage == POSE_STAGE:
        return "-" if value is None else f"{value:.1f}"
    if not _on_screen(state):
        return "n/a"
    return "skipped" if value is None else f"{value:.1f}"


def _performance_line(state: SessionState, display_fps: float) -> str:
    """The display's and the engine's rates and the recent latency; paused, the engine is said to be paused
    (its last rates and latencies are not current); without a prediction on screen (no head camera, none yet)
    the engine's figures are left out."""
    if state.playback is not None and state.playback.paused:
        return f"display {display_fps:.0f} fps, engine paused"
    if not _on_screen(state):
        return f"display {display_fps:.0f} fps, no prediction on screen"
    latency = state.history.get("latency_ms", np.zeros(0))[-30:]
    text = f"display {display_fps:.0f} fps, engine {state.engine_fps:.1f} fps"
    if latency.size:
        text += f", capture-to-prediction latency p50 {np.median(latency):.0f} ms, max {latency.max():.0f} ms (last 30)"
    return text


def _device_cells(status: SourceStatus) -> tuple[str, ...]:
    """The row's texts, each cut to its column's width."""
    rate = "" if status.rate_hz is None else f"{status.rate_hz:.0f} Hz"
    age = "" if status.age_ms is None else f"{status.age_ms:.0f} ms"
    name = VIEW_LABELS.get(status.name, status.name)
    if not status.in_scene:
        cells = (name, "not in this scene", "", "", "")
    else:
        state = ("ok" if status.connected else "DOWN") + (f" - {status.detail}" if status.detail else "")
        cells = (name, state, rate, age, str(status.drops))
    return tuple(text if len(text) <= chars else text[:chars - 1] + "…" for text, (_, chars) in zip(cells, DEVICE_COLUMNS))
