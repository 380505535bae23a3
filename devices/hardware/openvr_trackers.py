"""HTC Vive trackers through OpenVR (a running SteamVR): the poses of the configured trackers by role.

`openvr` is an optional dependency (`.venv/bin/pip install -e '.[trackers]'` in the checkout), imported only in connect().
Each poll asks OpenVR for every device's pose in the standing universe, keeps the generic trackers with
a valid pose, names them by serial number and maps serial → role (chest, left_wrist, right_wrist).

A pose is 7 float32: translation x, y, z in metres, then the orientation quaternion in the order
**w, x, y, z** (the order of this project's `vive_poses.json` and glove quaternions), with w ≥ 0.

Device gone: SteamVR quits (a `VREvent_Quit`, acknowledged) or an OpenVR call raises `OpenVRError`. The
shared reader (`ThreadedSource`) then shuts OpenVR down and calls `openvr.init` again with back-off until
SteamVR is back, counting `reconnects`; trackers keep their roles by serial number (device indices are
looked up afresh). A tracker that is switched off is not a lost device: its role is counted `missing`.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from touchanything.core.errors import UserError
from touchanything.core.snapshot import TRACKER_ROLES
from touchanything.devices.hardware.threaded_source import (
    DEFAULT_BACKOFF_S,
    DeviceLost,
    SourceCounters,
    ThreadedSource,
    check_backoff,
    now_us,
)

FLOAT32_MAX = float(np.finfo(np.float32).max)
INSTALL_HINT = "OpenVR trackers need the `openvr` package: .venv/bin/pip install -e '.[trackers]' in the checkout"


@dataclass(frozen=True)
class OpenVRTrackersConfig:
    """roles: tracker serial number (e.g. "LHR-1A2B3C4D") → role; rate_hz: polls per second;
    reconnect_backoff_s: (first, longest) wait between attempts to reach SteamVR again after it went away."""

    roles: dict[str, str]
    rate_hz: float = 90
    reconnect_backoff_s: tuple[float, float] = DEFAULT_BACKOFF_S

    def __post_init__(self) -> None:
        object.__setattr__(self, "reconnect_backoff_s", check_backoff(self.reconnect_backoff_s, "tracker"))
        if not self.roles:
            raise UserError("no Vive trackers configured; map each tracker serial to one of "
                            + ", ".join(TRACKER_ROLES))
        unknown = sorted(set(self.roles.values()) - set(TRACKER_ROLES))
        if unknown:
            raise UserError(f"unknown tracker role(s) {', '.join(unknown)}; choose from {', '.join(TRACKER_ROLES)}")
        if len(set(self.roles.values())) < len(self.roles):
            raise UserError("two tracker serials are mapped to the same role; give each role one tracker")
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise UserError(f"tracker rate must be a positive number of Hz, got {self.rate_hz}")


@dataclass(frozen=True)
class TrackerReading:
    """poses: {role: (7,) float32 x, y, z (m), qw, qx, qy, qz} for the roles with a valid pose at this poll;
    t_us: poll time on the host monotonic clock in µs."""

    poses: dict[str, np.ndarray]
    t_us: int


@dataclass
class TrackerCounters(SourceCounters):
    """missing: configured roles without a valid pose, summed over polls."""

    missing: int = 0


class TrackedPose(Protocol):
    """The fields used of openvr's TrackedDevicePose_t."""

    bPoseIsValid: bool
    mDeviceToAbsoluteTracking: Any
    """3×4 row-major device-to-standing-universe transform, indexable [row][column], metres."""


def pose_from_matrix(matrix: Any) -> np.ndarray | None:
    """A 3×4 row-major rigid transform (indexable [row][column]) as (7,) float32 x, y, z, qw, qx, qy, qz.

    The 3×3 part is replaced by the nearest rotation (tracking drift makes it slightly non-orthonormal);
    the quaternion is unit and canonical (w ≥ 0). None for non-finite, reflecting or degenerate input,
    or a translation beyond float32.
    """
    values = np.array([[float(matrix[row][col]) for col in range(4)] for row in range(3)])
    if not np.all(np.isfinite(values)) or np.abs(values[:, 3]).max() > FLOAT32_MAX:
        return None
    try:
        rotation = Rotation.from_matrix(values[:, :3])
    except (ValueError, np.linalg.LinAlgError):
        return None
    return np.concatenate([values[:, 3], rotation.as_quat(canonical=True, scalar_first=True)]).astype(np.float32)


def poses_by_role(poses: Sequence[TrackedPose], serials: Mapping[int, str],
                  roles: Mapping[str, str]) -> tuple[dict[str, np.ndarray], set[str]]:
    """One poll's pose array (indexed by device) → ({role: (7,) pose}, serials of trackers with no role).

    serials: device index → serial number of the generic trackers (other devices absent). A tracker is
    used when its pose is valid and its matrix is a proper rigid transform.
    """
    by_role: dict[str, np.ndarray] = {}
    unknown: set[str] = set()
    for index, serial in serials.items():
        if index >= len(poses) or not poses[index].bPoseIsValid:
            continue
        if serial not in roles:
            unknown.add(serial)
        elif (pose := pose_from_matrix(poses[index].mDeviceToAbsoluteTracking)) is not None:
            by_role[roles[serial]] = pose
    return by_role, unknown


def import_openvr() -> Any:
    """The `openvr` module, or a UserError saying how to install it."""
    try:
        import openvr
    except ImportError:
        raise UserError(INSTALL_HINT) from None
    return openvr


class OpenVRTrackers(ThreadedSource[TrackerReading]):
    """Polls OpenVR at `rate_hz` and publishes the configured trackers' poses by role."""

    def __init__(self, config: OpenVRTrackersConfig) -> None:
        super().__init__("Vive trackers", config.reconnect_backoff_s)
        self.config = config
        self._openvr: Any = None
        self._system: Any = None
        self._serials: dict[int, str | None] = {}
        self._unknown: set[str] = set()
        self._due_s = 0.0

    def _new_counters(self) -> TrackerCounters:
        return TrackerCounters()

    @property
    def counters(self) -> TrackerCounters:
        return super().counters  # type: ignore[return-value]

    def _open(self) -> None:
        openvr = self._openvr = import_openvr()
        try:
            self._system = openvr.init(openvr.VRApplication_Other)
        except openvr.OpenVRError as exc:
            raise UserError(f"OpenVR could not start ({exc}); SteamVR must be running, with the trackers "
                            f"switched on and paired") from None
        self._serials, self._unknown = {}, set()
        self._due_s = now_us() / 1e6

    def _step(self) -> None:
        now_s = now_us() / 1e6
        if (delay := self._due_s - now_s) > 0:
            self._stop.wait(delay)
            return
        self._due_s = max(self._due_s + 1.0 / self.config.rate_hz, now_s)
        openvr = self._openvr
        try:
            self._check_quit()
            poses = self._system.getDeviceToAbsoluteTrackingPose(
                openvr.TrackingUniverseStanding, 0, openvr.k_unMaxTrackedDeviceCount)
        except openvr.OpenVRError as exc:
            raise DeviceLost(f"OpenVR failed: {exc}") from None
        t_us = now_us()
        for index, pose in enumerate(poses):
            if pose.bPoseIsValid and index not in self._serials:
                self._serials[index] = self._tracker_serial(index)
        trackers = {index: serial for index, serial in self._serials.items() if serial is not None}
        by_role, unknown = poses_by_role(poses, trackers, self.config.roles)
        self._unknown = self._unknown | unknown
        self._publish(TrackerReading(by_role, t_us), t_us, missing=len(self.config.roles) - len(by_role))

    def _check_quit(self) -> None:
        """DeviceLost when SteamVR announced that it quits (the quit is acknowledged first)."""
        openvr, event = self._openvr, self._openvr.VREvent_t()
        while self._system.pollNextEvent(event):
            if event.eventType == openvr.VREvent_Quit:
                if (acknowledge := getattr(self._system, "acknowledgeQuit_Exiting", None)) is not None:
                    acknowledge()  # (not in every OpenVR release)
                raise DeviceLost("SteamVR quit")

    def _tracker_serial(self, index: int) -> str | None:
        """The serial number of device `index` when it is a generic tracker, else None."""
        openvr = self._openvr
        if self._system.getTrackedDeviceClass(index) != openvr.TrackedDeviceClass_GenericTracker:
            return None
        return self._system.getStringTrackedDeviceProperty(index, openvr.Prop_SerialNumber_String)

    def _status_details(self) -> str:
        """The serials of trackers seen that have no role."""
        unknown = sorted(self._unknown)
        return f", trackers without a role: {', '.join(unknown)}" if unknown else ""

    def _close(self) -> None:
        if self._system is not None:
            self._openvr.shutdown()
        self._openvr = self._system = None
