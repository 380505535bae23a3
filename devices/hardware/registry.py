"""The one registry of live device kinds: a scene's kind name → (config class, device class, role).

Scene files name a kind ("opencv", "oak", "jq", "rokoko", "openvr"; "camera" for hands estimated from the ego
camera); `device_kind` checks the name for a role (camera, glove, hands, trackers) and gives its config
class, and `create_device(config, cameras)` builds the device of any registered config (a kind that reads a
camera, like "camera" hands, is given that camera). Both the scene reader and the live rig use this table, so adding a kind
of device is one line here (and its config and device classes).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from touchanything.core.errors import UserError
from touchanything.devices.camera_pose.estimator import CameraPoseConfig
from touchanything.devices.hardware.camera_hands import CameraHands
from touchanything.devices.hardware.jq_glove import JQGlove, JQGloveConfig
from touchanything.devices.hardware.oak_camera import OakCamera, OakCameraConfig
from touchanything.devices.hardware.opencv_camera import OpenCVCamera, OpenCVCameraConfig
from touchanything.devices.hardware.openvr_trackers import OpenVRTrackers, OpenVRTrackersConfig
from touchanything.devices.hardware.rokoko_udp import RokokoConfig, RokokoReceiver
from touchanything.devices.hardware.threaded_source import ThreadedSource

ROLES = ("camera", "glove", "hands", "trackers")

CameraConfig = OakCameraConfig | OpenCVCameraConfig
"""The config of any camera kind."""


@dataclass(frozen=True)
class DeviceKind:
    """name: the kind as scene files write it; role: what it provides (one of ROLES); config: its frozen
    config dataclass; device: its ThreadedSource class, built as device(config), or device(config, camera)
    for a kind that `reads` the camera of a view; path_keys: settings that name files or device paths,
    resolved relative to the scene file when relative."""

    name: str
    role: str
    config: type
    device: Callable[..., ThreadedSource]
    path_keys: tuple[str, ...] = ()
    reads: str | None = None


KINDS: dict[str, DeviceKind] = {kind.name: kind for kind in (
    DeviceKind("opencv", "camera", OpenCVCameraConfig, OpenCVCamera, ("source",)),
    DeviceKind("oak", "camera", OakCameraConfig, OakCamera),
    DeviceKind("jq", "glove", JQGloveConfig, JQGlove, ("port",)),
    DeviceKind("rokoko", "hands", RokokoConfig, RokokoReceiver),
    DeviceKind("camera", "hands", CameraPoseConfig, CameraHands, ("model",), reads="ego"),
    DeviceKind("openvr", "trackers", OpenVRTrackersConfig, OpenVRTrackers),
)}


def kinds_for(role: str) -> tuple[str, ...]:
    """The kind names that provide `role`, in registration order."""
    return tuple(name for name, kind in KINDS.items() if kind.role == role)


def device_kind(name: object, role: str, key: str = "kind") -> DeviceKind:
    """The registered kind `name` for `role`; UserError ("<key> must be ...") listing the choices when there
    is none."""
    kind = KINDS.get(name) if isinstance(name, str) else None
    if kind is None or kind.role != role:
        choices = " or ".join(f'"{choice}"' for choice in kinds_for(role))
        raise UserError(f"{key} must be {choices}, got {name!r}")
    return kind


def kind_of(config: object) -> DeviceKind:
    """The registered kind whose config class `config` is; TypeError for an unregistered config."""
    for kind in KINDS.values():
        if type(config) is kind.config:
            return kind
    raise TypeError(f"no device kind is registered for {type(config).__name__}")


def create_device(config: object, cameras: dict[str, ThreadedSource] | None = None) -> ThreadedSource:
    """The (not yet connected) device of a registered config; a kind that reads a view's camera is given it
    from `cameras` (UserError when there is none)."""
    kind = kind_of(config)
    if kind.reads is None:
        return kind.device(config)
    camera = (cameras or {}).get(kind.reads)
    if camera is None:
        raise UserError(f'{kind.role} kind "{kind.name}" needs the {kind.reads} camera ([cameras.{kind.reads}])')
    return kind.device(config, camera)
