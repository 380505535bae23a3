"""The one registry of live device kinds: a scene's kind name → (config class, device class, role).

Scene files name a kind ("opencv", "oak", "jq", "rokoko", "openvr"); `device_kind` checks the name for a
role (camera, glove, hands, trackers) and gives its config class, and `create_device(config)` builds the
device of any registered config. Both the scene reader and the live rig use this table, so adding a kind
of device is one line here (and its config and device classes).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from touchanything.devices.errors import UserError
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
    config dataclass; device: its ThreadedSource class, built as device(config); path_keys: settings that
    name files or device paths, resolved relative to the scene file when relative."""

    name: str
    role: str
    config: type
    device: Callable[[Any], ThreadedSource]
    path_keys: tuple[str, ...] = ()


KINDS: dict[str, DeviceKind] = {kind.name: kind for kind in (
    DeviceKind("opencv", "camera", OpenCVCameraConfig, OpenCVCamera, ("source",)),
    DeviceKind("oak", "camera", OakCameraConfig, OakCamera),
    DeviceKind("jq", "glove", JQGloveConfig, JQGlove, ("port",)),
    DeviceKind("rokoko", "hands", RokokoConfig, RokokoReceiver),
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


def create_device(config: object) -> ThreadedSource:
    """The (not yet connected) device of a registered config."""
    return kind_of(config).device(config)
