"""What is attached, after lerobot's `find_cameras`: OpenCV cameras (/dev/video*), Luxonis OAK devices
(depthai), serial ports under /dev/serial/by-id (listened to for JQ glove packets), and Vive trackers
through OpenVR (SteamVR).

Every finder returns a `Discovery`: what it found and, when it found nothing, one phrase saying why
(nothing attached, a library missing, SteamVR not running). Finders never raise for absent hardware or
libraries, and they keep the libraries quiet while probing (OpenCV's probe warnings, depthai's import-time
log lines), so a machine without hardware gets one line per kind and nothing else. The places they look
are parameters, so tests can point them at real stand-ins (a folder of symlinks to a pty, a video file).
"""
from __future__ import annotations

import os
import re
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

import cv2

from touchanything.core.snapshot import HANDS
from touchanything.devices.hardware.camera_source import CameraFormat
from touchanything.devices.hardware.jq_glove import SERIAL_BY_ID, SERIAL_ERRORS, open_failure, open_port
from touchanything.devices.hardware.jq_protocol import JQStreamParser
from touchanything.devices.hardware.opencv_camera import OpenCVCameraConfig, negotiated_format, request_format
from touchanything.devices.hardware.openvr_trackers import INSTALL_HINT
from touchanything.devices.quiet_stderr import quiet_opencv

T = TypeVar("T")

DEV = Path("/dev")
V4L_BY_ID = Path("/dev/v4l/by-id")
VIDEO_NODE = re.compile(r"^video(\d+)$")
RIG_FORMAT = CameraFormat(640, 480, 30)
"""What a probed camera is asked for: the rig's format (the OpenCV camera config's defaults)."""
LISTEN_S = 0.3
"""How long each serial port is listened to for JQ glove packets (a glove sends 100 samples/s)."""
JQ_BAUDRATE = 921600


@dataclass(frozen=True)
class Discovery(Generic[T]):
    """found: what was found; reason: when nothing was, why (one phrase), else ""."""

    found: tuple[T, ...] = ()
    reason: str = ""


@dataclass(frozen=True)
class FoundCamera:
    """source: what a scene's `source` should say (a stable /dev/v4l/by-id link when there is one, else the
    device path or file); device: what was opened; format: what it negotiated when asked for the rig's."""

    source: int | str
    device: str
    format: CameraFormat


@dataclass(frozen=True)
class FoundOak:
    """An OAK device as depthai lists it: device_id (MxID), name (USB port or IP), state ("UNBOOTED", ...)."""

    device_id: str
    name: str
    state: str


@dataclass(frozen=True)
class FoundSerialPort:
    """port: the stable link; device: what it points at; sides: the glove sides heard on it (empty when no
    JQ packets were heard or it was not listened to); detail: one phrase about what was heard."""

    port: str
    device: str
    sides: tuple[str, ...]
    detail: str


@dataclass(frozen=True)
class FoundTracker:
    """A Vive tracker as SteamVR lists it: serial number, and whether its pose is valid now."""

    serial: str
    tracking: bool


# --- OpenCV cameras -------------------------------------------------------------------------------------


def video_devices(dev: Path = DEV) -> list[str]:
    """The /dev/video<N> nodes, in number order."""
    nodes = [(int(match[1]), path) for path in dev.glob("video*") if (match := VIDEO_NODE.match(path.name))]
    return [str(path) for _, path in sorted(nodes)]


def stable_links(by_id: Path) -> dict[str, str]:
    """Real device path → its stable link in `by_id` (the first in name order)."""
    links: dict[str, str] = {}
    if by_id.is_dir():
        for link in sorted(by_id.iterdir()):
            links.setdefault(os.path.realpath(link), str(link))
    return links


def probe_opencv(source: int | str, request: CameraFormat = RIG_FORMAT) -> CameraFormat | None:
    """Open `source` (index, device path or video file) as the OpenCV camera adapter would, ask a camera
    for `request`, read one frame; what it negotiated, or None when it does not open or gives no frame."""
    is_file = OpenCVCameraConfig(source).is_file
    capture = cv2.VideoCapture(str(source), cv2.CAP_FFMPEG) if is_file else cv2.VideoCapture(source)
    try:
        if not capture.isOpened():
            return None
        negotiated = negotiated_format(capture) if is_file else request_format(capture, request)
        ok, frame = capture.read()
        if not ok or frame is None:
            return None
        height, width = frame.shape[:2]
        return CameraFormat(width, height, negotiated.fps)
    finally:
        capture.release()


def find_opencv_cameras(sources: Sequence[int | str] | None = None, request: CameraFormat = RIG_FORMAT,
                        dev: Path = DEV, by_id: Path = V4L_BY_ID) -> Discovery[FoundCamera]:
    """The sources that open and deliver a frame; by default every /dev/video* node (under `dev`). A node
    with a stable link under `by_id` is reported by that link."""
    if sources is None:
        sources = video_devices(dev)
        if not sources:
            return Discovery(reason=f"nothing under {dev}/video*")
    links = stable_links(by_id)
    found = []
    with quiet_opencv():
        for source in sources:
            negotiated = probe_opencv(source, request)
            if negotiated is not None:
                name = links.get(os.path.realpath(source), source) if isinstance(source, str) else source
                found.append(FoundCamera(name, str(source), negotiated))
    tried = ", ".join(str(source) for source in sources)
    return Discovery(tuple(found), "" if found else f"none of {tried} opens as a camera (in use, or not a camera)")


# --- OAK cameras ----------------------------------------------------------------------------------------


def import_depthai() -> tuple[Any, str]:
    """(the depthai module, "") or (None, why it cannot be used); depthai's import-time log lines (e.g. "USB
    protocol not available") are kept quiet unless the user set DEPTHAI_LEVEL."""
    os.environ.setdefault("DEPTHAI_LEVEL", "error")
    try:
        import depthai
    except Exception as exc:  # noqa: BLE001 - a missing or broken native library is one line, not a traceback
        return None, f"depthai cannot be imported ({type(exc).__name__}: {exc})"
    return depthai, ""


def find_oak_cameras() -> Discovery[FoundOak]:
    """The OAK devices depthai can see (booted or not)."""
    dai, problem = import_depthai()
    if dai is None:
        return Discovery(reason=problem)
    try:
        infos = dai.Device.getAllAvailableDevices()
    except RuntimeError as exc:
        return Discovery(reason=f"depthai cannot search for devices ({exc})")
    found = tuple(FoundOak(info.getDeviceId(), info.name, getattr(info.state, "name", str(info.state)))
                  for info in infos)
    return Discovery(found, "" if found else "depthai sees no OAK device")


# --- serial ports (JQ gloves) ---------------------------------------------------------------------------


def listen_for_gloves(port: str, listen_s: float, baudrate: int = JQ_BAUDRATE) -> tuple[Counter[str], str]:
    """Listen to `port` for `listen_s` seconds: (JQ samples heard per side, "" or why it could not be read)."""
    try:
        serial_port, _ = open_port(port, baudrate, timeout_s=0.02)
    except SERIAL_ERRORS as exc:
        return Counter(), f"cannot open it: {open_failure(port, exc)}"
    parser, sides = JQStreamParser(), Counter()
    deadline = time.monotonic() + listen_s
    try:
        while time.monotonic() < deadline:
            sides.update(sample.side for sample in parser.feed(serial_port.read(serial_port.in_waiting or 1)))
    except SERIAL_ERRORS as exc:
        return sides, f"it stopped answering ({exc})"
    finally:
        serial_port.close()
    return sides, ""


def probe_serial_port(link: Path, listen_s: float = LISTEN_S) -> FoundSerialPort:
    """A serial port and, when `listen_s` > 0, which JQ glove sides were heard on it."""
    device = os.path.realpath(link)
    if listen_s <= 0:
        return FoundSerialPort(str(link), device, (), "not listened to")
    sides, problem = listen_for_gloves(str(link), listen_s)
    heard = tuple(side for side in HANDS if sides[side])
    if heard:
        rates = ", ".join(f"{side} {sides[side] / listen_s:.0f} samples/s" for side in heard)
        detail = f"JQ glove packets heard ({rates})"
    else:
        detail = problem or f"no JQ glove packets heard in {listen_s:g} s (not a glove, or switched off)"
    return FoundSerialPort(str(link), device, heard, detail)


def find_serial_ports(by_id: Path = SERIAL_BY_ID, listen_s: float = LISTEN_S) -> Discovery[FoundSerialPort]:
    """Every port under `by_id` (the stable names of USB serial devices), each listened to for JQ gloves."""
    links = sorted(by_id.iterdir()) if by_id.is_dir() else []
    if not links:
        return Discovery(reason=f"nothing under {by_id}")
    return Discovery(tuple(probe_serial_port(link, listen_s) for link in links))


# --- OpenVR trackers ------------------------------------------------------------------------------------


def find_openvr_trackers() -> Discovery[FoundTracker]:
    """The Vive trackers SteamVR knows; never starts SteamVR (a background OpenVR application)."""
    try:
        import openvr
    except ImportError:
        return Discovery(reason=f"the openvr package is not installed; {INSTALL_HINT.split(': ', 1)[1]}")
    except Exception as exc:  # noqa: BLE001 - a broken native library is one line, not a traceback
        return Discovery(reason=f"openvr cannot be imported ({type(exc).__name__}: {exc})")
    if not openvr.isRuntimeInstalled():
        return Discovery(reason="no OpenVR runtime is installed (install SteamVR)")
    try:
        system = openvr.init(openvr.VRApplication_Background)
    except openvr.OpenVRError as exc:
        return Discovery(reason=f"SteamVR is not running ({exc})")
    try:
        found = tuple(_trackers(openvr, system))
    finally:
        openvr.shutdown()
    return Discovery(found, "" if found else "SteamVR runs but lists no Vive tracker (switched on and paired?)")


def _trackers(openvr: Any, system: Any) -> Iterator[FoundTracker]:
    poses = system.getDeviceToAbsoluteTrackingPose(openvr.TrackingUniverseStanding, 0, openvr.k_unMaxTrackedDeviceCount)
    for index in range(openvr.k_unMaxTrackedDeviceCount):
        if system.getTrackedDeviceClass(index) == openvr.TrackedDeviceClass_GenericTracker:
            serial = system.getStringTrackedDeviceProperty(index, openvr.Prop_SerialNumber_String)
            yield FoundTracker(serial, bool(poses[index].bPoseIsValid))
