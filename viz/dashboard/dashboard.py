"""The dearpygui dashboard: cameras with hand overlays, measured / predicted (or an ensemble's spread) / error
pressure maps, contact lamps, running metrics, latency per stage, device status, and the session's controls.

The render loop runs on the calling thread and never waits for devices or the engine: between frames it
sleeps until the session publishes a new record (`wait_for_news`: a snapshot with its prediction, about 30 a
second for a 30 fps replay) or the next frame is due. Every panel of a drawn frame comes from one `ShownFrame`
(the session's published snapshot and prediction, the prediction's truth and facts, the views and the display
settings), replaced in one step: the cameras are redrawn on a new snapshot, the head camera's pressure discs,
the maps, titles, lamps, metrics table and legends on a new prediction, together. A frame is rendered when that
record changed, or the user is acting (for INPUT_HOLD_S after any mouse or key event or control callback), at
most MAX_FPS times a second; otherwise only every IDLE_PERIOD_S, which is when dearpygui looks at the mouse and
keyboard. The plots' lines (at most 5 times a second), the text tables (10) and the atlas are refreshed on their
own clocks and go on screen with the next frame: they never add one. So the display draws at the content's rate
and leaves the CPU to the engine and to other programs (docs/bench/dashboard.md measures it). Callbacks run on
the same thread (manual callback management), between frames.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import dearpygui.dearpygui as dpg
import matplotlib
import numpy as np

from touchanything.core.errors import UserError
from touchanything.core.output_safety import replacing
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.devices.rate_meter import RateMeter
from touchanything.viz.dashboard.atlas_panel import AtlasPanel
from touchanything.viz.dashboard.dashboard_controls import Tables, build_controls, build_tables
from touchanything.viz.dashboard.dashboard_drawn import ContactLamps, HistoryPlots
from touchanything.viz.dashboard.dashboard_panels import blank, camera_panel, pressure_views
from touchanything.viz.dashboard.dashboard_state import DashboardSession, SessionState
from touchanything.viz.dashboard.render_priority import lower_rasterizer_threads
from touchanything.viz.dashboard.shown_frame import ShownFrame
from touchanything.viz.display import display_problem
from touchanything.viz.pressure_panel import HAND_LABELS, MAP_GAP, MAP_TITLES, maps_width, unposed_as_nan
from touchanything.viz.textures import TextureSlot

CAMERA = (256, 192)
CAMERA_TEXTURE = (192, 144)
"""Camera textures are smaller than drawn (CAMERA): dearpygui re-uploads every raw texture every frame."""
CELL = 7
MAPS = (maps_width(CELL), 21 * CELL)
CONTACT = (460, 64)
PLOTS = (MAPS[0], MAPS[1] + 40)
ATLAS = (3 * CAMERA[0] + 16, 118)
MAP_NAMES = tuple(MAP_TITLES)
MAP_COLUMN_GAP = 60
WINDOW_COLOUR = (37, 37, 38)
"""The viewport is cleared to this colour and the full-screen window draws no background of its own:
under software OpenGL a blended full-screen quad costs about half of an otherwise empty frame."""
REFRESH_PERIODS_S = {"plots": 0.2, "tables": 0.1, "atlas": 0.5}
"""The plots and the text tables are refreshed at most this often (every frame would only cost CPU)."""
MAX_FPS = 60
"""Frames are rendered at most this often (about a display's refresh rate, for input; content changes at 30 Hz)."""
IDLE_PERIOD_S = 0.2
"""With nothing changing, a frame is still rendered this often: dearpygui reads input only while rendering."""
INPUT_HOLD_S = 1.0
"""After the last input event or control callback, frames are rendered at MAX_FPS for this long (drags,
hover highlights, typing)."""
FONT_SIZE = 13
CHAR_WIDTH = 0.517 * FONT_SIZE
"""The font is monospaced; dearpygui scales it so that ascent − descent is FONT_SIZE pixels, and DejaVu Sans
Mono advances 0.517 of that per character."""
SPREAD_TIPS = {True: "show the members' spread (how much the ensemble's models disagree) instead of the predicted pressure",
               False: "one model: no spread"}
"""The spread toggle's tooltip, by whether an ensemble runs."""
DISABLED_TEXT = (128, 128, 128)
"""A disabled control's label colour (dearpygui draws it as an enabled one's otherwise)."""
BEND_TIP = ("hatched grey cells: the finger bend (flex) sensors — how far a finger is bent, not pressure — on their own "
            "grey scale (lighter: more bent); contact, the lamps and the outline use the tactile cells only")
"""The maps' tooltip: what the hatched cells are (`pressure_panel`)."""
HAND_LABEL_SPACING = 21 * CELL + MAP_GAP - round(len(HAND_LABELS[0]) * CHAR_WIDTH)
"""Puts the right hand's label under the right map."""


@dataclass(frozen=True)
class DashboardConfig:
    width: int = 1280
    height: int = 720
    title: str = "TouchAnything Live"
    screenshot_dir: Path = Path("recordings") / "screenshots"


@dataclass
class DashboardStats:
    """frames rendered over `seconds`; camera_lag_ms / prediction_lag_ms: now − capture time when a new
    camera frame / prediction reached the screen."""

    frames: int = 0
    seconds: float = 0.0
    rate: RateMeter = field(default_factory=RateMeter)
    """Frames rendered per second recently."""
    camera_lag_ms: list[float] = field(default_factory=list)
    prediction_lag_ms: list[float] = field(default_factory=list)

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0


class Dashboard:
    """`run()` opens the window and returns when it is closed (or after `max_frames`)."""

    def __init__(self, session: DashboardSession, config: DashboardConfig = DashboardConfig()) -> None:
        self.session = session
        self.config = config
        self.stats = DashboardStats()
        self.outline = False
        self.spread = False
        """The predicted map shows the members' spread (while an ensemble runs)."""
        self.pending_screenshot: Path | None = None
        self.saved_screenshots: list[Path] = []
        self.note = ""
        self._closing = False
        self.panel_rects: dict[str, tuple[int, int, int, int]] = {}
        """Where each image panel is on screen: name → (x, y, width, height) in viewport pixels."""
        self._frame = ShownFrame()
        """What the panels show (`_update`)."""
        self._refreshed: dict[str, object] = {}
        """What the plots' lines, the atlas and the spread toggle show (`_changed`)."""
        self._due = dict.fromkeys(REFRESH_PERIODS_S, 0.0)
        self._tables = Tables()
        self._input_until = 0.0
        self._last_frame = 0.0
        self._frame_due = True
        """The shown record changed since the last rendered frame."""

    def run(self, max_frames: int | None = None, screenshot: Path | None = None) -> DashboardStats:
        """Render until the window closes or `max_frames` frames; with `screenshot`, the content stops
        changing after `max_frames` and that last frame (what `shown` holds) is saved there as PNG.
        Raises UserError when no X display is reachable (checked before dearpygui starts: it would abort
        the process). The session is closed before the GUI is torn down (its threads must not run while
        dearpygui destroys its context). One dashboard per process: dearpygui 2.x does not survive a
        second context next to running decoder threads."""
        problem = display_problem()
        if problem:
            self.session.close()
            raise UserError(f"cannot open the dashboard: {problem}")
        dpg.create_context()
        try:
            dpg.configure_app(manual_callback_management=True)
            self._build()
            dpg.create_viewport(title=self.config.title, width=self.config.width, height=self.config.height,
                                x_pos=0, y_pos=0)
            dpg.setup_dearpygui()
            dpg.show_viewport()
            dpg.set_primary_window("main", True)
            dpg.configure_item("main", no_background=True)
            dpg.set_viewport_clear_color((*WINDOW_COLOUR, 255))
            self._loop(max_frames, screenshot)
        finally:
            self.session.close()
            dpg.destroy_context()
        return self.stats

    def _bind_font(self) -> None:
        """DejaVu Sans Mono (shipped with matplotlib): dearpygui's built-in font has ASCII glyphs only, and
        the messages of the devices and the engine use arrows, dashes and signs such as ≤ − × →."""
        path = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSansMono.ttf"
        with dpg.font_registry():
            dpg.bind_font(dpg.add_font(str(path), FONT_SIZE))

    def _build(self) -> None:
        self._bind_font()
        with dpg.texture_registry() as registry:
            self.cameras = {view: TextureSlot(registry, *CAMERA_TEXTURE) for view in VIEW_NAMES}
            self.maps = {name: TextureSlot(registry, *MAPS) for name in MAP_NAMES}
        with dpg.window(tag="main"):
            with dpg.group(horizontal=True):
                with dpg.group():
                    with dpg.group(horizontal=True):
                        for view in VIEW_NAMES:
                            dpg.add_image(self.cameras[view].tag, tag=f"image_{view}", width=CAMERA[0],
                                          height=CAMERA[1])
                    for row in (("measured", "predicted"), ("error", None)):
                        with dpg.group(horizontal=True, horizontal_spacing=MAP_COLUMN_GAP):
                            for name in row:
                                with dpg.group():
                                    if name is None:
                                        self.plots = HistoryPlots(*PLOTS)
                                        continue
                                    dpg.add_text("", tag=f"title_{name}")
                                    dpg.add_image(self.maps[name].tag, tag=f"image_{name}", width=MAPS[0], height=MAPS[1])
                                    with dpg.tooltip(f"image_{name}"):
                                        dpg.add_text(BEND_TIP, wrap=400)
                                    with dpg.group(horizontal=True, horizontal_spacing=HAND_LABEL_SPACING):
                                        for label in HAND_LABELS:
                                            dpg.add_text(label)
                                        if name == "predicted":
                                            self._build_spread_toggle()
                    self.atlas = AtlasPanel(*ATLAS)
                with dpg.group():
                    build_controls(self)
                    self.lamps = ContactLamps(*CONTACT)
                    build_tables(CHAR_WIDTH)
        with dpg.handler_registry():
            for add_handler in (dpg.add_mouse_move_handler, dpg.add_mouse_down_handler, dpg.add_mouse_wheel_handler,
                                dpg.add_key_down_handler):
                add_handler(callback=_noted)

    def _build_spread_toggle(self) -> None:
        """The "spread" checkbox under the predicted map's colour bar: the members' spread instead of the predicted
        pressure; disabled until an ensemble runs, its tooltip saying why (`_show_spread_toggle`)."""
        dpg.add_checkbox(label="spread", tag="spread_toggle", enabled=False,
                         callback=lambda s, value: setattr(self, "spread", bool(value)))
        with dpg.tooltip("spread_toggle"):
            dpg.add_text(SPREAD_TIPS[False], tag="spread_tip")
        with dpg.theme() as theme:
            for enabled in (True, False):
                with dpg.theme_component(dpg.mvCheckbox, enabled_state=enabled):
                    dpg.add_theme_style(dpg.mvStyleVar_FramePadding, 4, 0)  # as high as the hand labels beside it
                    if not enabled:
                        dpg.add_theme_color(dpg.mvThemeCol_Text, DISABLED_TEXT)
        dpg.bind_item_theme("spread_toggle", theme)

    def _show_spread_toggle(self, members: int) -> bool:
        """Enable the spread toggle while an ensemble (`members` > 1) runs; True when that changed."""
        ensemble = members > 1
        if not self._changed("ensemble", ensemble):
            return False
        dpg.configure_item("spread_toggle", enabled=ensemble)
        dpg.set_value("spread_tip", SPREAD_TIPS[ensemble])
        return True

    def _loop(self, max_frames: int | None, screenshot: Path | None) -> None:
        start = time.perf_counter()
        news = -1
        while dpg.is_dearpygui_running() and not self._closing:
            callbacks = dpg.get_callback_queue()
            if callbacks:
                self._input_until = time.perf_counter() + INPUT_HOLD_S
                dpg.run_callbacks(callbacks)
            if max_frames is None or self.stats.frames < max_frames:
                state = self.session.state()
                news = state.news
                self._frame_due |= self._update(state)
            wait = self._until_frame(time.perf_counter())
            if wait > 0:
                news = self.session.wait_for_news(news, wait)
                continue
            self._last_frame, self._frame_due = time.perf_counter(), False
            dpg.render_dearpygui_frame()
            if not self.panel_rects:
                self._find_panels()
                lower_rasterizer_threads()  # created by the first frame
            self.stats.frames += 1
            self.stats.rate.tick()
            self.stats.seconds = time.perf_counter() - start
            if max_frames is not None and self.stats.frames >= max_frames:
                if screenshot is None or screenshot in self.saved_screenshots:
                    break
                if self.pending_screenshot is None and self.stats.frames > max_frames:
                    # one frame rendered after the content stopped changing: requested on the frame of the last
                    # texture upload, the saved image sometimes held the previous maps (2 of 9 test runs; 0 of 24
                    # with this extra frame)
                    self.request_screenshot(screenshot)

    def _until_frame(self, now: float) -> float:
        """Seconds until the next frame is due (≤ 0: render now): 1 / MAX_FPS after the last one for a new record,
        a screenshot, the first layout and while the user acts; otherwise IDLE_PERIOD_S after it."""
        urgent = self._frame_due or self.pending_screenshot or not self.panel_rects or now < self._input_until
        return self._last_frame + (1 / MAX_FPS if urgent else IDLE_PERIOD_S) - now

    def close(self) -> None:
        """Ask the render loop to end (callable from any thread; within IDLE_PERIOD_S)."""
        self._closing = True

    @property
    def shown(self) -> dict[str, object]:
        """What is on screen now: the snapshot, the prediction and the views used of the shown record."""
        frame = self._frame
        return {"snapshot": frame.snapshot, "prediction": frame.prediction, "views": frame.views_used}

    def _find_panels(self) -> None:
        """Record the panels' screen rectangles once dearpygui has laid them out."""
        rects = {}
        items = {**{name: f"image_{name}" for name in (*VIEW_NAMES, *MAP_NAMES)}, "atlas": self.atlas.drawlist}
        for name, item in items.items():
            (x, y), (w, h) = dpg.get_item_rect_min(item), dpg.get_item_rect_size(item)
            rects[name] = (int(x), int(y), int(w), int(h))
        if all(w > 0 and h > 0 for _, _, w, h in rects.values()):
            self.panel_rects = rects

    def _changed(self, key: str, value: object) -> bool:
        """Whether `value` differs from what is on screen under `key` (identity, or equality for tuples and
        flags), remembering it."""
        shown = self._refreshed.get(key, ...)
        if shown is value or (isinstance(value, (tuple, bool)) and shown == value):
            return False
        self._refreshed[key] = value
        return True

    def _update(self, state: SessionState) -> bool:
        """Bring what is shown up to `state`; True when the shown record (or the spread toggle) changed: a frame is
        due. Everything the record decides is drawn from it together; the plots' lines, the atlas and the tables
        are refreshed on their own clocks and go on screen with the next frame."""
        frame = ShownFrame(state.snapshot, state.prediction, state.truth, state.facts, state.views_used, state.members,
                           (self.session.threshold, self.outline, self.spread))
        new_cameras, new_maps = frame.new_cameras(self._frame), frame.new_maps(self._frame)
        if new_cameras or new_maps:
            self._draw(frame, new_cameras, new_maps)
        self._frame = frame
        new_toggle = self._show_spread_toggle(state.members)
        self._refresh(state)
        return new_cameras or new_maps or new_toggle

    def _draw(self, frame: ShownFrame, new_cameras: bool, new_maps: bool) -> None:
        """Draw `frame`: the cameras and the pose line (`new_cameras`), the head camera's discs, the maps, their
        titles, the lamps, the legends and the metrics table (`new_maps`)."""
        now_us = time.monotonic_ns() / 1000
        prediction, facts = frame.prediction, frame.facts
        shown = None if prediction is None or facts is None else prediction.pressure
        pressure = None if shown is None else unposed_as_nan(shown, facts.posed)  # the skeleton's discs, as the map
        for view in VIEW_NAMES if new_cameras else ("ego",):
            self.cameras[view].show(camera_panel(frame.snapshot, view, view in frame.views_used, *CAMERA_TEXTURE,
                                                 pressure))
        if new_cameras:
            self._tables.show_pose(frame.snapshot)
            if frame.snapshot is not None and frame.snapshot is not self._frame.snapshot:
                self.stats.camera_lag_ms.append((now_us - frame.snapshot.t_us) / 1e3)
        if not new_maps:
            return
        state = SessionState(snapshot=frame.snapshot, prediction=prediction, truth=frame.truth, facts=facts,
                             members=frame.members)
        for name, (image, title) in pressure_views(state, CELL, *frame.settings).items():
            self.maps[name].show(blank(*MAPS, "n/a") if image is None else image)
            dpg.set_value(f"title_{name}", title)
        self.lamps.update(facts)
        predicted = facts is not None and facts.predicted  # a latency only of a prediction on screen
        self.plots.show_values(None if facts is None else facts.rolling, prediction.latency_ms if predicted else None)
        self._tables.show_metrics(facts)
        if prediction is not None and prediction is not self._frame.prediction:
            self.stats.prediction_lag_ms.append((now_us - prediction.t_us) / 1e3)

    def _refresh(self, state: SessionState) -> None:
        """The plots' lines, the atlas and the tables, each when due and changed."""
        if self._refresh_due("plots") and self._changed("history", tuple(v.tobytes() for v in state.history.values())):
            self.plots.update(state.history)
        if self._changed("atlas", state.atlas):
            self.atlas.show_atlas(state.atlas, state.atlas_note)
        predicted = state.facts is not None and state.facts.predicted  # the shown record, as the maps
        running = (state.setting, None if state.step_p99_ms is None else round(state.step_p99_ms, 1), state.steps_timed,
                   predicted, state.accuracy.caption)
        if self._refresh_due("atlas") and self._changed("running", running):
            self.atlas.update(*running)
        if self._refresh_due("tables"):
            self._tables.update(state, self.note, self.stats.rate.rate())

    def _refresh_due(self, name: str) -> bool:
        """Whether `name` is due for a refresh (then the next one is scheduled)."""
        now = time.perf_counter()
        if now < self._due[name]:
            return False
        self._due[name] = now + REFRESH_PERIODS_S[name]
        return True

    def request_screenshot(self, path: Path | None = None) -> None:
        """Save the next rendered frame as PNG (default: a timestamped file under the screenshot folder)."""
        if path is None:
            path = free_name(self.config.screenshot_dir / time.strftime("dashboard_%Y%m%d_%H%M%S.png"))
        self.pending_screenshot = Path(path)
        self.note = f"saving a screenshot: {self.pending_screenshot.name}"
        dpg.output_frame_buffer(callback=self._save_screenshot)

    def _save_screenshot(self, sender: object, buffer: object) -> None:
        path, self.pending_screenshot = self.pending_screenshot, None
        width, height = dpg.get_viewport_client_width(), dpg.get_viewport_client_height()
        rgba = np.frombuffer(buffer, np.float32)
        pixels = rgba.size // 4
        height = pixels // width if width and pixels % width == 0 else height
        image = (np.clip(rgba.reshape(height, -1, 4)[..., :3], 0, 1) * 255).round().astype(np.uint8)
        encoded, png = cv2.imencode(".png", image[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
        try:
            if not encoded:
                raise UserError(f"{path}: the image could not be encoded")
            with replacing(path) as temporary:
                temporary.write_bytes(png.tobytes())
        except UserError as exc:
            self.note = f"screenshot not saved: {exc}"
            return
        self.saved_screenshots.append(path)
        self.note = f"screenshot saved: {path.name}\nin {path.parent}"  # a long path wraps, never the name


def free_name(path: Path) -> Path:
    """`path`, or `stem_2.png`, `stem_3.png`, … when taken: a screenshot never replaces another file."""
    candidate, number = Path(path), 2
    while os.path.lexists(candidate):
        candidate, number = path.with_name(f"{path.stem}_{number}{path.suffix}"), number + 1
    return candidate


def _noted(*_: object) -> None:
    """An input handler's callback: its arrival in the callback queue is what keeps frames coming."""
