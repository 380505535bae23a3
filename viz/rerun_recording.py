"""Rerun recordings of a session (`--rerun FILE.rrd`, `--rerun-serve`), laid out by `viz.rerun_blueprint`.

Every row is on two timelines: `frame` (the episode's frame index, or the live rig's tick) and `capture_time`
(seconds from the episode's or the session's first frame). Entities:

- `cameras/{ego,wrist_left,wrist_right}`: the episode's own MP4 as a video asset with one frame reference per
  frame (`log_videos`), else a JPEG per frame (`log_observation`); `cameras/ego/hands`: both skeletons projected
  into the head camera; `cameras/{view}/not_used`: while the model takes nothing from a view, a point at the
  image's top left labelled "left wrist camera — not used" (`view_sets.view_label`), cleared when it is used again.
- `world/hands`: both hands' 3D joints with their bones, class 0 the left hand and 1 the right, keypoints in the
  official joint order and named (`wrist`, `thumb_1` … `pinky_4`: shown on hover) (WiLoR's head-camera frame:
  metres, x right, y down, z forward); `world/surface/{left,right}`: the hand surface with vertex normals, painted
  with the measured and with the predicted map (`viz.rerun_hands`).
- `pressure/{measured,predicted}`: both 21×21 maps side by side (left | right, one transparent column between)
  as an RGBA PNG on the official colour scale (blue 0 → red 1, as in the dashboard), cells outside the layout in
  the dashboard's background colour; beneath it, the values themselves, `pressure/{measured,predicted}/{left,right}`:
  one (21, 21) float16 depth image per hand (meter 1, fixed range 0–1, Turbo; NaN outside the layout), so that
  hovering a cell shows its pressure ("Val") and its grid position (x: column, y: row; the right hand's image
  placed 22 cells to the right). `pressure/difference`: predicted − measured on [−1, 1] (blue: too low, red: too
  high), as a PNG. `pressure/spread` (an ensemble's only, from its first spread on, with its view added to the
  layout): the members' spread as a PNG on [0, SPREAD_HIGH] with `pressure/spread/{left,right}` beneath.
- `contact/{measured,predicted}`: the official contact rule per hand, [left, right], 0 or 1, NaN (a gap) for a
  hand that map does not have (not predicted: no pose; no glove sample) — the frame's `FrameFacts`.
- `metrics/{rolling,cumulative}`: the official metrics `SHOWN_METRICS` over the last 3 s and over everything so
  far (the frame's `FrameFacts`; NaN where undefined).
- `engine`: [capture-to-prediction latency, the engine's time for the step] in ms.
- `trackers/{chest,left_wrist,right_wrist}`: the Vive tracker poses as transforms (OpenVR frame, y up).

A hand without a valid pose, a missing map or prediction is cleared at its frame (nothing stale is shown); a
hand the model did not predict is background on the predicted and the difference map, as in the dashboard. Entities
are grouped so that a frame takes about 20 log calls: the calls, not the bytes, are what logging costs.
"""
from __future__ import annotations

import os
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path

import cv2
import numpy as np
import rerun as rr

from touchanything.core.hand_pose import project_wilor
from touchanything.core.snapshot import HANDS, TRACKER_ROLES, VIEW_NAMES
from touchanything.core.temporary_files import mark, temporary_path, unmark
from touchanything.core.view_sets import view_label
from touchanything.viz.colormap import ERROR_LUT, PRESSURE_LUT, apply
from touchanything.viz.frame_facts import FrameFacts
from touchanything.viz.pressure_panel import BACKGROUND, SPREAD_HIGH, unposed_as_nan
from touchanything.viz.rerun_accounting import SERVER_MEMORY_LIMIT, CountingStream, ServedHistory
from touchanything.viz.rerun_blueprint import MAP_ENTITIES, SHOWN_METRICS, SPREAD_ENTITY, default_blueprint
from touchanything.viz.rerun_columns import ColumnBuffer
from touchanything.viz.rerun_hands import HandSurfaces, hand_classes
from touchanything.viz.rerun_serving import ANY, LOCALHOST, ServedAt, free_port

APPLICATION = "touchanything"
JPEG_QUALITY = 75
VALUE_GAP = 22
"""Columns from the left hand's value image to the right hand's (its 21 and the gap column of the PNG)."""
VALUE_DTYPE = np.float16
"""The value images' type: 11 significant bits (a value in [0.5, 1] within 0.00025), half the bytes of float32."""
NOT_USED_AT, NOT_USED_COLOUR = (8.0, 8.0), (150, 150, 150)
"""Where, in image pixels, and in which colour a view the model does not use is labelled so."""
MAP_DRAW_ORDER, VALUE_DRAW_ORDER = -10.0, -20.0
"""The coloured map is drawn over the value images (Rerun's defaults for images and depth images)."""
FLUSH_SECONDS, FLUSH_BYTES = 0.5, 8 << 20
"""Rows are batched into chunks for half a second (or 8 MiB): one chunk per frame and entity would cost more
in chunk headers than the data, and the file's footer keeps an entry per chunk in memory while recording."""


@dataclass(frozen=True)
class RerunTarget:
    """Where a recording goes: `rrd`, a file (written under a temporary name in its folder and renamed when the
    recording closes); `serve_port`, a web viewer on that HTTP port fed by a gRPC server on `serve_host`
    (127.0.0.1: this machine only) at `grpc_port` (0: a free one, read back; `viz.rerun_serving`). `image_scale`
    scales camera frames logged as JPEG (the live rig's). `server_memory_limit`: bytes the data server keeps at most
    (beyond it, the oldest rows go: `viz.rerun_accounting`)."""

    rrd: Path | None = None
    serve_port: int | None = None
    grpc_port: int = 0
    image_scale: float = 1.0
    serve_host: str = LOCALHOST
    server_memory_limit: int = SERVER_MEMORY_LIMIT


def map_image(grids: np.ndarray, lut: np.ndarray, low: float, high: float = 1.0) -> np.ndarray:
    """Both hands' (2, 21, 21) maps on the fixed scale [low, high] of `lut`, side by side with a column between,
    as a (21, 43, 4) RGBA image; cells outside the layout (NaN) are the dashboard's background (opaque: they
    cover the value images beneath), the gap between the hands is transparent."""
    values = np.full((21, 43), np.nan, np.float32)
    values[:, :21], values[:, VALUE_GAP:] = grids[0], grids[1]
    rgba = np.full((21, 43, 4), 255, np.uint8)
    rgba[..., :3] = apply(values, lut, low, high, BACKGROUND)
    rgba[:, 21:VALUE_GAP, 3] = 0
    return rgba


class RerunRecording:
    """One Rerun recording. Methods may be called from any thread, one at a time; rows are sent in batches
    (`viz.rerun_columns`), each with its own frame and time.
    `close()` flushes, writes the file's footer and renames it into place; `served` says where it is watched
    when serving (`url`: its web viewer). OSError when a port is in use or the address is not this machine's."""

    def __init__(self, target: RerunTarget, name: str, properties: Mapping[str, str]) -> None:
        self.target = target
        self.served: ServedAt | None = None
        if target.serve_port is not None:
            try:
                free_port(ANY[0], target.serve_port)  # Rerun's web server listens on every interface
            except OSError as exc:
                raise OSError(f"the web viewer's port: {exc}") from None
            self.served = ServedAt(target.serve_host, free_port(target.serve_host, target.grpc_port), target.serve_port)
        batching = rr.ChunkBatcherConfig(flush_tick=timedelta(seconds=FLUSH_SECONDS), flush_num_bytes=FLUSH_BYTES)
        self._stream = rr.RecordingStream(APPLICATION, send_properties=True, batcher_config=batching)
        self.history = ServedHistory(target.server_memory_limit)
        """What was sent, and what the data server may have dropped of it (`line()`)."""
        self._log = CountingStream(self._stream, self.history)
        sinks = []
        if target.rrd is not None:
            target.rrd.parent.mkdir(parents=True, exist_ok=True)  # the output check creates nothing
            mark(temporary_path(target.rrd), "file")
            sinks.append(rr.FileSink(temporary_path(target.rrd)))
        if self.served is not None:
            limit = f"{target.server_memory_limit}B"
            sinks.append(rr.GrpcServerSink(bind_ip=self.served.host, port=self.served.grpc_port, server_memory_limit=limit))
        self._stream.set_sinks(*sinks, default_blueprint=default_blueprint())
        if self.served is not None:
            rr.serve_web_viewer(web_port=self.served.web_port, open_browser=False, connect_to=self.served.data_url)
        self._stream.send_recording_name(name)
        if properties:
            self._stream.send_property("session", rr.AnyValues(**{k: str(v) for k, v in properties.items()}))
        self._rows = ColumnBuffer(self._log)  # the stream's calls that log rows, counted
        self._videos: set[str] = set()
        self._image_size: dict[str, tuple[int, int]] = {}
        self._unused: dict[str, bool] = {}
        """Per view: marked "not used" now."""
        self._surfaces = HandSurfaces(self._rows)
        self._spread = False
        """An ensemble's spread has been logged (its entities and view are set up)."""
        self._log_static()

    @property
    def url(self) -> str | None:
        """The web viewer's address when serving, else None."""
        return None if self.served is None else self.served.web_url

    def _log_static(self) -> None:
        log = self._log.log
        log("/", hand_classes(), static=True)
        log("world", rr.ViewCoordinates.RDF, static=True)
        log("trackers", rr.ViewCoordinates.RUB, static=True)
        for role in TRACKER_ROLES:
            log(f"trackers/{role}", rr.TransformAxes3D(0.1), static=True)
        HandSurfaces.log_static(self._log)
        for kind, colours in (("measured", ((90, 200, 255), (60, 120, 255))), ("predicted", ((255, 170, 90), (255, 90, 60)))):
            log(f"contact/{kind}", rr.SeriesLines(colors=colours, names=[f"{hand} {kind}" for hand in HANDS]), static=True)
        log("metrics/rolling", rr.SeriesLines(names=[f"{name} (3 s)" for name in SHOWN_METRICS]), static=True)
        log("metrics/cumulative", rr.SeriesLines(names=[f"{name} (all)" for name in SHOWN_METRICS],
                                                 widths=[1.0] * len(SHOWN_METRICS)), static=True)
        log("engine", rr.SeriesLines(names=["latency ms", "engine step ms"]), static=True)
        log("world/hands", rr.Points3D.from_fields(radii=0.004, show_labels=False), static=True)
        for view in VIEW_NAMES:
            log(f"cameras/{view}/not_used", rr.Points2D.from_fields(labels=[view_label(view, False)], colors=[NOT_USED_COLOUR],
                                                                     show_labels=True), static=True)
        log("cameras/ego/hands", rr.Points2D.from_fields(radii=2.5, show_labels=False), static=True)
        for kind in MAP_ENTITIES.values():
            log(f"pressure/{kind}", rr.EncodedImage.from_fields(media_type="image/png", magnification_filter="nearest",
                                                                opacity=1.0, draw_order=MAP_DRAW_ORDER), static=True)
        for kind in ("measured", "predicted"):
            self._log_value_images(kind, 1.0)

    def _log_value_images(self, kind: str, high: float) -> None:
        """The static part of `pressure/{kind}/{left,right}`: (21, 21) VALUE_DTYPE depth images on [0, high]."""
        value_type = rr.encodings.ChannelDatatype.from_np_dtype(np.dtype(VALUE_DTYPE))
        value_format = rr.components.ImageFormat(width=21, height=21, channel_datatype=value_type)
        for hand in HANDS:
            self._log.log(f"pressure/{kind}/{hand}", rr.DepthImage.from_fields(
                format=value_format, meter=1.0, depth_range=(0.0, high), colormap="turbo", magnification_filter="nearest",
                draw_order=VALUE_DRAW_ORDER), static=True)
        self._log.log(f"pressure/{kind}/right", rr.Transform3D(translation=(VALUE_GAP, 0.0, 0.0)), static=True)

    def log_videos(self, videos: Mapping[str, Path], frames: int, times_s: np.ndarray,
                   sizes: Mapping[str, tuple[int, int]]) -> set[str]:
        """Log each view's MP4 (`videos` {view: path}) as a video asset with a reference for each of its first
        `frames` frames at `times_s` (frames,); `sizes` {view: (width, height)}. Returns the views logged;
        a file Rerun cannot read as a video (or that has fewer frames) is left out, to go as JPEG frames."""
        for view, path in videos.items():
            try:
                asset = rr.AssetVideo(path=path)
                stamps = asset.read_frame_timestamps_nanos()
            except (RuntimeError, ValueError, OSError):
                continue
            if len(stamps) < frames:
                continue
            self._log.log(f"cameras/{view}", asset, static=True)
            indexes = [rr.TimeColumn("frame", sequence=np.arange(frames)),
                       rr.TimeColumn("capture_time", duration=np.asarray(times_s[:frames], np.float64))]
            self._log.send_columns(f"cameras/{view}", indexes=indexes,
                                   columns=rr.VideoFrameReference.columns_nanos(stamps[:frames]))
            self._videos.add(view)
            self._image_size[view] = sizes[view]
        return set(self._videos)

    def log_observation(self, frame: int, time_s: float, images: Mapping[str, np.ndarray], joints: np.ndarray,
                        valid: np.ndarray, measured: np.ndarray | None, facts: FrameFacts,
                        trackers: Mapping[str, np.ndarray], used: Collection[str] = VIEW_NAMES) -> None:
        """What the rig saw at `frame`: camera frames {view: (H, W, 3) uint8 RGB} (views logged as videos are
        skipped), joints (42, 3) with valid (2,), the measured map (2, 21, 21) (None: no glove) and its contact
        as `facts` (of this frame) decided it, tracker poses {role: (7,) trans + rot w, x, y, z}; `used`: the
        views the model takes anything from (the others are marked "not used" from this frame on)."""
        at = (frame, time_s)
        for view, image in images.items():
            if view not in self._videos:
                self._log_image(view, image, at)
        self._mark_unused(used, at)
        self._log_skeletons(joints, valid, at)
        self._log_map("measured", measured, PRESSURE_LUT, 0.0, at)
        self._log_values("measured", measured, at)
        self._surfaces.paint("measured", at, joints, valid, measured)
        if facts.measured:
            self._rows.put("contact/measured", rr.Scalars, *at, scalars=facts.contact("measured"))
        for role in TRACKER_ROLES:
            pose = trackers.get(role)
            if pose is None or not np.isfinite(pose).all():
                self._rows.clear(f"trackers/{role}", *at)
            else:
                xyzw = np.asarray(pose, np.float32)[[4, 5, 6, 3]]
                self._rows.put(f"trackers/{role}", rr.Transform3D, *at, translation=np.asarray(pose[None, :3], np.float32),
                               quaternion=xyzw[None])

    def log_prediction(self, frame: int, time_s: float, predicted: np.ndarray | None, facts: FrameFacts, joints: np.ndarray,
                       valid: np.ndarray, measured: np.ndarray | None, latency_ms: float | None, step_ms: float | None,
                       spread: np.ndarray | None = None) -> None:
        """The prediction for `frame` ((2, 21, 21) or None; a hand `facts` says was not predicted is shown as
        none), painted on that frame's joints; its difference to `measured`; its contact and the running official
        metrics as the frame's `facts` hold them; the latency and the engine step (None: not known); an
        ensemble's `spread` (2, 21, 21) beside it (None: a single model's prediction, or none)."""
        at = (frame, time_s)
        if predicted is not None:
            predicted = unposed_as_nan(predicted, facts.posed)
        self._log_map("predicted", predicted, PRESSURE_LUT, 0.0, at)
        self._log_values("predicted", predicted, at)
        self._surfaces.paint("predicted", at, joints, valid, predicted)
        self._log_spread(None if predicted is None or spread is None else unposed_as_nan(spread, facts.posed), at)
        if facts.predicted:
            self._rows.put("contact/predicted", rr.Scalars, *at, scalars=facts.contact("predicted"))
        difference = None if predicted is None or measured is None else predicted - measured
        self._log_map("difference", difference, ERROR_LUT, -1.0, at)
        timings = np.array([np.nan if value is None else value for value in (latency_ms, step_ms)], np.float64)
        self._rows.put("engine", rr.Scalars, *at, scalars=timings)
        for kind, values in (("rolling", facts.rolling), ("cumulative", facts.cumulative)):
            if values is not None:
                scalars = np.array([np.nan if values[n] is None else values[n] for n in SHOWN_METRICS], np.float64)
                self._rows.put(f"metrics/{kind}", rr.Scalars, *at, scalars=scalars)

    def _log_spread(self, spread: np.ndarray | None, at: tuple[int, float]) -> None:
        """The spread map and values (None: cleared once there has been one); the first adds the spread's
        entities and its view to the layout."""
        if spread is not None and not self._spread:
            self._spread = True
            self._log.log(f"pressure/{SPREAD_ENTITY}", rr.EncodedImage.from_fields(
                media_type="image/png", magnification_filter="nearest", opacity=1.0, draw_order=MAP_DRAW_ORDER), static=True)
            self._log_value_images(SPREAD_ENTITY, SPREAD_HIGH)
            self._stream.send_blueprint(default_blueprint(spread=True))
        if self._spread:
            self._log_map(SPREAD_ENTITY, spread, PRESSURE_LUT, 0.0, at, SPREAD_HIGH)
            self._log_values(SPREAD_ENTITY, spread, at)

    def _mark_unused(self, used: Collection[str], at: tuple[int, float]) -> None:
        """Show the "not used" label on the views outside `used`, and take it off the others, where that changed
        (its text and colour are static; a row places it, a clear takes it away)."""
        for view in VIEW_NAMES:
            unused = view not in used
            if unused != self._unused.get(view, False):
                self._unused[view] = unused
                if unused:
                    self._rows.put(f"cameras/{view}/not_used", rr.Points2D, *at, positions=np.array([NOT_USED_AT], np.float32))
                else:
                    self._rows.clear(f"cameras/{view}/not_used", *at)

    def _log_image(self, view: str, image: np.ndarray, at: tuple[int, float]) -> None:
        scale = self.target.image_scale
        height, width = image.shape[:2]
        self._image_size[view] = (width, height)
        if scale != 1.0:
            image = cv2.resize(image, (max(1, round(width * scale)), max(1, round(height * scale))), interpolation=cv2.INTER_AREA)
        ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(image, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if ok:
            self._rows.put(f"cameras/{view}", rr.EncodedImage, *at, blob=[jpeg.tobytes()], media_type=["image/jpeg"])

    def _log_skeletons(self, joints: np.ndarray, valid: np.ndarray, at: tuple[int, float]) -> None:
        """Both hands' joints in 3D and projected into the head camera (its image as logged)."""
        hands = np.asarray(joints, np.float32).reshape(2, 21, 3)
        shown = [h for h in range(2) if valid[h] and np.isfinite(hands[h]).all()]
        if not shown:
            self._rows.clear("world/hands", *at)
            self._rows.clear("cameras/ego/hands", *at)
            return
        points, classes = hands[shown].reshape(-1, 3), np.repeat(np.array(shown, np.uint16), 21)
        keypoints = np.tile(np.arange(21, dtype=np.uint16), len(shown))
        self._rows.put("world/hands", rr.Points3D, *at, positions=points, class_ids=classes, keypoint_ids=keypoints)
        size = self._image_size.get("ego")
        pixels = None if size is None else project_wilor(points, *size) * (1.0 if "ego" in self._videos else self.target.image_scale)
        if pixels is None or not np.isfinite(pixels).all():
            self._rows.clear("cameras/ego/hands", *at)
        else:
            self._rows.put("cameras/ego/hands", rr.Points2D, *at, positions=pixels.astype(np.float32), class_ids=classes,
                           keypoint_ids=keypoints)

    def _log_map(self, kind: str, grids: np.ndarray | None, lut: np.ndarray, low: float, at: tuple[int, float],
                 high: float = 1.0) -> None:
        if grids is None:
            self._rows.clear(f"pressure/{kind}", *at)
        else:
            ok, png = cv2.imencode(".png", cv2.cvtColor(map_image(grids, lut, low, high), cv2.COLOR_RGBA2BGRA))
            if ok:
                self._rows.put(f"pressure/{kind}", rr.EncodedImage, *at, blob=[png.tobytes()])

    def _log_values(self, kind: str, grids: np.ndarray | None, at: tuple[int, float]) -> None:
        """Each hand's (21, 21) map as the VALUE_DTYPE buffer of its value image (None: cleared)."""
        for h, hand in enumerate(HANDS):
            if grids is None:
                self._rows.clear(f"pressure/{kind}/{hand}", *at)
            else:
                self._rows.put(f"pressure/{kind}/{hand}", rr.DepthImage, *at, buffer=[np.asarray(grids[h], VALUE_DTYPE).tobytes()])

    def flush(self) -> None:
        """Send every row held back and wait until the sinks have it: from then on the data server holds all that
        was logged (a viewer connecting while a finished session is still served gets all of it)."""
        if self._stream is not None:
            self._rows.flush()
            self._stream.flush()

    def close(self) -> None:
        """Flush, close the sinks (the file gets its footer) and rename the file into place; idempotent."""
        if self._stream is None:
            return
        self.flush()
        stream, self._stream = self._stream, None
        stream.disconnect()
        if self.target.rrd is not None and temporary_path(self.target.rrd).exists():
            os.replace(temporary_path(self.target.rrd), self.target.rrd)
        if self.target.rrd is not None:
            unmark(temporary_path(self.target.rrd))
