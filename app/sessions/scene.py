"""Scene files (TOML): which live sources exist and their settings. Only what a scene lists is built
(model only what the scene has). Relative paths are relative to the scene file.

    [clock]               rate_hz = 30, stale_after_ms = 200
    [cameras.<view>]      view: ego | wrist_left | wrist_right; kind = "oak" (device_id, socket) or
                          "opencv" (source = device index or video file, loop)
    [gloves.<hand>]       hand: left | right; kind = "jq" (the default); port (a stable /dev/serial/by-id
                          path), baudrate
    [hands]               source = "rokoko" (the default; host, port, actor; needs [pose]) or "camera" (hands
                          estimated from [cameras.ego], bare hands only: mirror, smoothing,
                          handedness_frames, model)
    [trackers]            kind = "openvr" (the default); rate_hz; [trackers.roles] serial = "chest" |
                          "left_wrist" | "right_wrist"
    [pose]                the calibration that brings mocap joints into the head-camera frame
    [model]               checkpoint, config, and the engine setting's runtime, precision, views, every, output,
                          invalid_hands, device (default: the bundled pico model, torch fp32, device auto: the
                          first CUDA GPU when there is one, else the CPU); onnx_dir = an export-onnx folder to
                          run (runtime onnx; checkpoint: the one it was exported from)
    [simulator]           episode = a recorded episode the simulated rig replays through the real
                          protocols (pty gloves, Rokoko UDP to [hands]; cameras are its video files in
                          [cameras]); link_dir for the gloves' serial links
    [recording]           fsync_s = seconds between fsyncs of every file of a recording (1.0; 0: after every
                          frame; false: never)

Which kinds exist, and the config class of each, come from the device registry
(`touchanything.devices.hardware.registry`), which the live rig uses to build the devices.
"""
from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from touchanything.app.sessions.engine_choice import ModelChoice, choose, default_checkpoint, export_choice
from touchanything.app.sessions.scene_values import check_types
from touchanything.core.errors import UserError
from touchanything.core.snapshot import HANDS, VIEW_NAMES
from touchanything.devices.camera_pose.estimator import CameraPoseConfig
from touchanything.devices.camera_pose.model_file import read_model
from touchanything.devices.hardware.jq_glove import JQGloveConfig
from touchanything.devices.hardware.openvr_trackers import OpenVRTrackersConfig
from touchanything.devices.hardware.registry import CameraConfig, device_kind
from touchanything.devices.hardware.rokoko_udp import RokokoConfig
from touchanything.devices.rig.recorder import valid_fsync_s
from touchanything.devices.rig.rig_clock import RigClockConfig
from touchanything.devices.sim.device_emulator import SimulatedRigConfig
from touchanything.inference.engine.engine_setting import EngineSetting

MODEL_FILES = ("checkpoint", "config", "onnx_dir")
"""The [model] settings that name files (paths against the scene's folder); the others are the engine setting's."""
SECTIONS = ("clock", "cameras", "gloves", "hands", "trackers", "pose", "model", "simulator", "recording")


@dataclass(frozen=True)
class RecordingSettings:
    """[recording] fsync_s: seconds between fsyncs of every file of a recording, what a power loss can lose
    (0: after every frame; None, `false` in the scene file: never)."""

    fsync_s: float | None = 1.0


@dataclass(frozen=True)
class Scene:
    path: Path
    clock: RigClockConfig = RigClockConfig()
    cameras: dict[str, CameraConfig] = field(default_factory=dict)
    gloves: dict[str, JQGloveConfig] = field(default_factory=dict)
    hands: RokokoConfig | CameraPoseConfig | None = None
    trackers: OpenVRTrackersConfig | None = None
    pose: dict[str, Any] = field(default_factory=dict)
    model: ModelChoice = field(default_factory=lambda: choose(default_checkpoint()))
    simulator: SimulatedRigConfig | None = None
    recording: RecordingSettings = RecordingSettings()


def read_scene(path: Path) -> Scene:
    """Parse and check a scene file; every problem is one UserError naming the file and the key (a camera-pose
    scene's hand model file: naming that file)."""
    path = Path(path)
    try:
        table = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise UserError(f"{path}: scene file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read the scene file ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: not valid TOML ({exc})") from None
    unknown = sorted(set(table) - set(SECTIONS))
    if unknown:
        raise UserError(f"{path}: unknown section(s) {', '.join(unknown)}; sections are {', '.join(SECTIONS)}")
    base = path.resolve().parent
    try:
        _check_tables(table)
        scene = Scene(
            path=path, clock=_build(RigClockConfig, "clock", table.get("clock", {})),
            cameras={view: _device(f"cameras.{view}", "camera", s, base)
                     for view, s in _named(table, "cameras", VIEW_NAMES).items()},
            gloves={hand: _device(f"gloves.{hand}", "glove", s, base, default="jq", side=hand)
                    for hand, s in _named(table, "gloves", HANDS).items()},
            hands=_device("hands", "hands", table["hands"], base, "source", "rokoko") if "hands" in table else None,
            trackers=_device("trackers", "trackers", table["trackers"], base, default="openvr")
            if "trackers" in table else None,
            pose=dict(table.get("pose", {})), model=_model(table.get("model", {}), base),
            simulator=_simulator(table["simulator"], table.get("hands", {}), base) if "simulator" in table else None,
            recording=_recording(table.get("recording", {})))
        if isinstance(scene.hands, CameraPoseConfig) and "ego" not in scene.cameras:
            raise UserError('[hands] source = "camera" estimates the hands from the ego camera: add [cameras.ego]')
    except UserError as exc:
        raise UserError(f"{path}: {exc}") from None
    if isinstance(scene.hands, CameraPoseConfig):
        read_model(scene.hands.model)  # a missing or changed hand model is refused before any device starts
    return scene


def scene_inputs(scene: Scene) -> list[Path]:
    """The files a scene reads besides itself: the episode its simulated rig replays, the video files its cameras
    play, its model's checkpoint (what a command that records it must never write over)."""
    files = [scene.path, scene.model.checkpoint]
    files += [scene.simulator.episode] if scene.simulator is not None else []
    files += [Path(c.source) for c in scene.cameras.values()
              if isinstance(getattr(c, "source", None), str) and not str(c.source).startswith("/dev/")]
    return files


def _build(cls, section: str, settings: dict):
    """cls(**settings), naming the section and the key when a key is unknown, missing or of the wrong type
    (the config's own checks then name impossible values)."""
    fields = dataclasses.fields(cls) if dataclasses.is_dataclass(cls) else ()
    missing = [f.name for f in fields if f.name not in settings
               and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    if missing:
        raise UserError(f"[{section}] needs a {' and a '.join(missing)} setting")
    check_types(cls, section, settings)
    try:
        return cls(**settings)
    except TypeError as exc:
        message = str(exc).split("()", 1)[-1].strip()
        raise UserError(f"[{section}] {message}") from None


def _check_tables(table: dict) -> None:
    """Every section, and every named entry of [cameras] and [gloves], must be a TOML table."""
    for section, value in table.items():
        if not isinstance(value, dict):
            raise UserError(f"[{section}] must be a table, got {value!r}")
    for section in ("cameras", "gloves"):
        for name, value in table.get(section, {}).items():
            if not isinstance(value, dict):
                raise UserError(f"[{section}.{name}] must be a table, got {value!r}")


def _named(table: dict, section: str, names: tuple[str, ...]) -> dict[str, dict]:
    entries = table.get(section, {})
    unknown = sorted(set(entries) - set(names))
    if unknown:
        raise UserError(f"[{section}]: unknown name(s) {', '.join(unknown)}; choose from {', '.join(names)}")
    return entries


def _resolve(section: str, key: str, value: Any, base: Path) -> Path:
    """A path setting relative to the scene's folder; anything but text is one line naming the key."""
    if not isinstance(value, str) or not value or "\0" in value:
        raise UserError(f"[{section}] {key}: expected a path, got {value!r}")
    return Path(value) if Path(value).is_absolute() else base / value


def _device(section: str, role: str, settings: dict, base: Path, kind_key: str = "kind", default: str | None = None,
            **fixed: Any) -> Any:
    """The config of one device section: its kind looked up in the registry for `role` (the `kind_key`
    setting, else `default`), its path settings resolved against the scene's folder, `fixed` added."""
    settings = dict(settings)
    try:
        kind = device_kind(settings.pop(kind_key, default), role, kind_key)
    except UserError as exc:
        raise UserError(f"[{section}] {exc}") from None
    for key in kind.path_keys:
        if isinstance(settings.get(key), str):
            settings[key] = str(_resolve(section, key, settings[key], base))
    return _build(kind.config, section, {**fixed, **settings})


def _model(settings: dict, base: Path) -> ModelChoice:
    """[model]: its files (`MODEL_FILES`, paths against the scene's folder) and the engine setting's knobs
    (`EngineSetting`'s fields but `model`); with `onnx_dir`, that export (`export_choice`)."""
    knobs = {k: v for k, v in settings.items() if k not in MODEL_FILES}
    files = {k: _resolve("model", k, v, base) for k, v in settings.items() if k in MODEL_FILES}
    names = MODEL_FILES + tuple(f.name for f in dataclasses.fields(EngineSetting) if f.name != "model")
    if unknown := sorted(set(settings) - set(names)):
        raise UserError(f"[model] unknown name(s) {', '.join(unknown)}; choose from {', '.join(names)}")
    check_types(EngineSetting, "model", knobs)
    if files.get("onnx_dir") is not None:
        return export_choice(files["onnx_dir"], checkpoint=files.get("checkpoint"), config=files.get("config"), **knobs)
    return choose(files.get("checkpoint", default_checkpoint()), files.get("config"), **knobs)


def _simulator(settings: dict, hands: dict, base: Path) -> SimulatedRigConfig:
    """The simulated rig sends its Rokoko datagrams to where [hands] listens."""
    settings = dict(settings)
    if "episode" not in settings:
        raise UserError("[simulator] needs an episode to replay")
    for key in ("episode", "link_dir"):
        if key in settings:
            settings[key] = _resolve("simulator", key, settings[key], base)
    receiver = RokokoConfig(**{k: v for k, v in hands.items() if k in ("host", "port")})
    return _build(SimulatedRigConfig, "simulator", {"rokoko_host": receiver.host, "rokoko_port": receiver.port,
                                                     **settings})


def _recording(settings: dict) -> RecordingSettings:
    """`fsync_s = false` is None (never); any other value than seconds ≥ 0 is one line naming the key."""
    settings = dict(settings)
    if settings.get("fsync_s", 1.0) is False:
        settings["fsync_s"] = None
    elif not valid_fsync_s(settings.get("fsync_s", 1.0)):
        raise UserError(f"[recording] fsync_s: expected seconds ≥ 0 (0: after every frame) or false (never), "
                        f"got {settings['fsync_s']!r}")
    return _build(RecordingSettings, "recording", settings)
