"""Scene files (TOML): which live sources exist and their settings. Only what a scene lists is built
(model only what the scene has). Relative paths are relative to the scene file.

    [clock]               rate_hz = 30, stale_after_ms = 200
    [cameras.<view>]      view: ego | wrist_left | wrist_right; kind = "oak" (device_id, socket) or
                          "opencv" (source = device index or video file, loop)
    [gloves.<hand>]       hand: left | right; port (a stable /dev/serial/by-id path), baudrate
    [hands]               source = "rokoko"; host, port, actor
    [trackers]            rate_hz; [trackers.roles] serial = "chest" | "left_wrist" | "right_wrist"
    [pose]                the calibration that brings mocap joints into the head-camera frame
    [model]               checkpoint, runtime, precision (default: the bundled nano model, torch fp32)
    [simulator]           episode = a recorded episode the simulated rig replays through the real
                          protocols (pty gloves, Rokoko UDP to [hands]; cameras are its video files in
                          [cameras]); link_dir for the gloves' serial links
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from touchanything.app.sessions.engine_choice import ModelChoice, default_checkpoint
from touchanything.devices.errors import UserError
from touchanything.devices.hardware.jq_glove import JQGloveConfig
from touchanything.devices.hardware.oak_camera import OakCameraConfig
from touchanything.devices.hardware.opencv_camera import OpenCVCameraConfig
from touchanything.devices.hardware.openvr_trackers import OpenVRTrackersConfig
from touchanything.devices.hardware.rokoko_udp import RokokoConfig
from touchanything.devices.rig.rig_clock import RigClockConfig
from touchanything.devices.sim.device_emulator import SimulatedRigConfig
from touchanything.devices.snapshot import HANDS, VIEW_NAMES

SECTIONS = ("clock", "cameras", "gloves", "hands", "trackers", "pose", "model", "simulator")


@dataclass(frozen=True)
class Scene:
    path: Path
    clock: RigClockConfig = RigClockConfig()
    cameras: dict[str, OakCameraConfig | OpenCVCameraConfig] = field(default_factory=dict)
    gloves: dict[str, JQGloveConfig] = field(default_factory=dict)
    hands: RokokoConfig | None = None
    trackers: OpenVRTrackersConfig | None = None
    pose: dict[str, Any] = field(default_factory=dict)
    model: ModelChoice = field(default_factory=lambda: ModelChoice(default_checkpoint()))
    simulator: SimulatedRigConfig | None = None


def read_scene(path: Path) -> Scene:
    """Parse and check a scene file; every problem is one UserError naming the file and the key."""
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
        return Scene(
            path=path, clock=_build(RigClockConfig, "clock", table.get("clock", {})),
            cameras={view: _camera(view, s, base) for view, s in _named(table, "cameras", VIEW_NAMES).items()},
            gloves={hand: _glove(hand, s, base) for hand, s in _named(table, "gloves", HANDS).items()},
            hands=_hands(table["hands"]) if "hands" in table else None,
            trackers=_trackers(table["trackers"]) if "trackers" in table else None,
            pose=dict(table.get("pose", {})), model=_model(table.get("model", {}), base),
            simulator=_simulator(table["simulator"], table.get("hands", {}), base) if "simulator" in table else None)
    except UserError as exc:
        raise UserError(f"{path}: {exc}") from None


def _build(cls, section: str, settings: dict):
    """cls(**settings), naming the section and the keys when a key is unknown or missing."""
    try:
        return cls(**settings)
    except TypeError as exc:
        message = str(exc).split("()", 1)[-1].strip()
        raise UserError(f"[{section}] {message}") from None


def _named(table: dict, section: str, names: tuple[str, ...]) -> dict[str, dict]:
    entries = table.get(section, {})
    unknown = sorted(set(entries) - set(names))
    if unknown:
        raise UserError(f"[{section}]: unknown name(s) {', '.join(unknown)}; choose from {', '.join(names)}")
    return entries


def _resolve(value: str, base: Path) -> str:
    return str(value if Path(value).is_absolute() else base / value)


def _camera(view: str, settings: dict, base: Path) -> OakCameraConfig | OpenCVCameraConfig:
    settings = dict(settings)
    kind = settings.pop("kind", None)
    if kind == "oak":
        return _build(OakCameraConfig, f"cameras.{view}", settings)
    if kind == "opencv":
        if isinstance(settings.get("source"), str):
            settings["source"] = _resolve(settings["source"], base)
        return _build(OpenCVCameraConfig, f"cameras.{view}", settings)
    raise UserError(f"[cameras.{view}] kind must be \"oak\" or \"opencv\", got {kind!r}")


def _glove(hand: str, settings: dict, base: Path) -> JQGloveConfig:
    settings = dict(settings)
    if "port" not in settings:
        raise UserError(f"[gloves.{hand}] needs a port")
    settings["port"] = _resolve(settings["port"], base)
    if "reconnect_backoff_s" in settings:
        settings["reconnect_backoff_s"] = tuple(settings["reconnect_backoff_s"])
    return _build(JQGloveConfig, f"gloves.{hand}", {"side": hand, **settings})


def _hands(settings: dict) -> RokokoConfig:
    settings = dict(settings)
    source = settings.pop("source", "rokoko")
    if source != "rokoko":
        raise UserError(f"[hands] source must be \"rokoko\", got {source!r}")
    return _build(RokokoConfig, "hands", settings)


def _trackers(settings: dict) -> OpenVRTrackersConfig:
    return _build(OpenVRTrackersConfig, "trackers", settings)


def _model(settings: dict, base: Path) -> ModelChoice:
    settings = dict(settings)
    for key in ("checkpoint", "config"):
        if key in settings:
            settings[key] = Path(_resolve(settings[key], base))
    return _build(ModelChoice, "model", {"checkpoint": default_checkpoint(), **settings})


def _simulator(settings: dict, hands: dict, base: Path) -> SimulatedRigConfig:
    """The simulated rig sends its Rokoko datagrams to where [hands] listens."""
    settings = dict(settings)
    if "episode" not in settings:
        raise UserError("[simulator] needs an episode to replay")
    settings["episode"] = Path(_resolve(settings["episode"], base))
    if "link_dir" in settings:
        settings["link_dir"] = Path(_resolve(settings["link_dir"], base))
    receiver = RokokoConfig(**{k: v for k, v in hands.items() if k in ("host", "port")})
    return _build(SimulatedRigConfig, "simulator", {"rokoko_host": receiver.host, "rokoko_port": receiver.port,
                                                     **settings})
