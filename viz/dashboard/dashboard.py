"""The dearpygui dashboard: cameras with hand overlays, measured / predicted (or an ensemble's spread) / error
pressure maps, contact lamps, running metrics, latency per stage, device status, and the session's controls.

The render loop runs on the calling thread and never waits for devices or the engine: it polls the
session's latest state at the display rate and rebuilds an image only when its content changed (cameras
on a new snapshot, maps on a new prediction; plots are refreshed at most 5 and tables 10 times a second).
A frame is rendered only when something on screen changed or the user is acting (for INPUT_HOLD_S after
any mouse or key event or control callback), at most MAX_FPS times a second; otherwise only every
IDLE_PERIOD_S, which is when dearpygui looks at the mouse and keyboard. So a paused replay leaves the CPU
to the engine and to other programs (docs/bench/dashboard.md measures it). Callbacks run on the same
thread (manual callback management), between frames.
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

from touchanything.devices.errors import UserError
from touchanything.devices.output_safety import replacing
from touchanything.devices.rate_meter import RateMeter
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.viz.dashboard.atlas_panel import AtlasPanel
from touchanything.viz.dashboard.dashboard_controls import Tables, build_controls, build_tables
from touchanything.viz.dashboard.dashboard_drawn import ContactLamps, HistoryPlots
from touchanything.viz.dashboard.dashboard_panels import blank, camera_panel, pressure_views
from touchanything.viz.dashboard.dashboard_state import DashboardSession, SessionState
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
"""Frames are rendered at most this often (about a display's refresh rate; content changes at 30 Hz)."""
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
        self._shown: dict[str, object] = {}
        self._due = dict.fromkeys(REFRESH_PERIODS_S, 0.0)
        self._tables = Tables()
        self._input_until = 0.0

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
        start = last_frame = time.perf_counter()
        changed = True
        while dpg.is_dearpygui_running() and not self._closing:
            callbacks = dpg.get_callback_queue()
            if callbacks:
                self._input_until = time.perf_counter() + INPUT_HOLD_S
                dpg.run_callbacks(callbacks)
            finishing = max_frames is not None and self.stats.frames >= max_frames
            if not finishing:
                changed |= self._update(self.session.state())
            now = time.perf_counter()
            if not (changed or now < self._input_until or self.pending_screenshot or now >= last_frame + IDLE_PERIOD_S
                    or not self.panel_rects):
                time.sleep(1 / MAX_FPS)
                continue
            time.sleep(max(0.0, last_frame + 1 / MAX_FPS - now))
            last_frame, changed = time.perf_counter(), False
            dpg.render_dearpygui_frame()
            if not self.panel_rects:
                self._find_panels()
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

    def close(self) -> None:
        """Ask the render loop to end after the current frame (callable from any thread)."""
        self._closing = True

    @property
    def shown(self) -> dict[str, object]:
        """What is on screen now: the snapshot and prediction records last uploaded."""
        return dict(self._shown)

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
        """Whether `value` differs from what is on screen under `key` (identity for records, equality for
        settings tuples), remembering it."""
        shown = self._shown.get(key, ...)
        if shown is value or (isinstance(value, tuple) and shown == value):
            return False
        self._shown[key] = value
        return True

    def _update(self, state: SessionState) -> bool:
        """Bring what is shown up to `state`; True when anything on screen changed."""
        now_us = time.monotonic_ns() / 1000
        prediction, facts = state.prediction, state.facts
        new_prediction = self._changed("prediction", prediction)
        new_snapshot = self._changed("snapshot", state.snapshot) | self._changed("views", state.views_used)
        if new_snapshot or (new_prediction and prediction is None):  # restarted figures: the old discs go too
            shown = None if prediction is None or facts is None else prediction.pressure
            pressure = None if shown is None else unposed_as_nan(shown, facts.posed)  # the skeleton's discs, as the map
            for view in VIEW_NAMES if new_snapshot else ("ego",):
                self.cameras[view].show(camera_panel(state.snapshot, view, view in state.views_used, *CAMERA_TEXTURE,
                                                     pressure))
            if new_snapshot and state.snapshot is not None:
                self.stats.camera_lag_ms.append((now_us - state.snapshot.t_us) / 1e3)
        new_toggle = self._show_spread_toggle(state.members)
        settings = (self.session.threshold, self.outline, state.truth is None, self.spread, state.members > 1)
        new_maps = new_prediction | self._changed("facts", facts) | self._changed("settings", settings)
        if new_maps:  # everything the prediction's facts decide, together: the panels never disagree
            views = pressure_views(state, CELL, self.session.threshold, self.outline, self.spread)
            for name, (image, title) in views.items():
                self.maps[name].show(blank(*MAPS, "n/a") if image is None else image)
                dpg.set_value(f"title_{name}", title)
            self.lamps.update(facts)
            self.plots.show_values(None if facts is None else facts.rolling, None if prediction is None else prediction.latency_ms)
            self._tables.show_metrics(facts)
        if new_prediction and prediction is not None:
            self.stats.prediction_lag_ms.append((now_us - prediction.t_us) / 1e3)
        changed = new_snapshot | new_maps | new_toggle
        if self._refresh_due("plots") and self._changed("history", tuple(v.tobytes() for v in state.history.values())):
            self.plots.update(state.history)
            changed = True
        if self._changed("atlas", state.atlas):
            self.atlas.show_atlas(state.atlas, state.atlas_note)
            changed = True
        running = (state.setting, None if state.step_p99_ms is None else round(state.step_p99_ms, 1))
        if self._refresh_due("atlas") and self._changed("running", running):
            self.atlas.update(*running)
            changed = True
        if self._refresh_due("tables"):
            changed |= self._tables.update(state, self.note, self.stats.rate.rate())
        return changed

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
