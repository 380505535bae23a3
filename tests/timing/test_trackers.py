"""Vive trackers through OpenVR: matrix → (trans, quaternion w,x,y,z), pose arrays → roles, options, and the
user error when the optional `openvr` package is not installed (it is not, here)."""
from __future__ import annotations

import importlib.util
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from touchanything.core.errors import UserError
from touchanything.devices.hardware.openvr_trackers import (
    INSTALL_HINT,
    OpenVRTrackers,
    OpenVRTrackersConfig,
    pose_from_matrix,
    poses_by_role,
)


@dataclass
class Pose:
    """Test double at the data level for openvr's TrackedDevicePose_t (no OpenVR runtime exists here)."""

    bPoseIsValid: bool
    mDeviceToAbsoluteTracking: list[list[float]]


def transform(rotation: np.ndarray, trans: np.ndarray) -> list[list[float]]:
    return np.hstack([rotation, np.asarray(trans, float)[:, None]]).tolist()


def matrix_of(pose: np.ndarray) -> np.ndarray:
    w, x, y, z = pose[3:].astype(float)
    return Rotation.from_quat([x, y, z, w]).as_matrix()


finite = st.floats(-100, 100, allow_nan=False)
unit_quats = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: np.linalg.norm(q) > 0.1)


@settings(max_examples=300, deadline=None)
@given(unit_quats, st.tuples(finite, finite, finite))
def test_random_rotations_round_trip(quat_xyzw, trans):
    rotation = Rotation.from_quat(quat_xyzw)
    pose = pose_from_matrix(transform(rotation.as_matrix(), trans))
    assert pose.shape == (7,) and pose.dtype == np.float32
    np.testing.assert_allclose(pose[:3], np.float32(trans), rtol=0, atol=0)
    assert pose[3] >= 0 and np.linalg.norm(pose[3:]) == pytest.approx(1, abs=1e-6)
    expected = rotation.as_quat(canonical=True)  # x, y, z, w
    assert abs(np.dot(pose[3:], np.roll(expected, 1))) == pytest.approx(1, abs=1e-6)
    np.testing.assert_allclose(matrix_of(pose), rotation.as_matrix(), atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda a: np.linalg.norm(a) > 0.1), st.floats(0, 1e-4))
def test_rotations_near_half_a_turn_stay_accurate(axis, epsilon):
    rotation = Rotation.from_rotvec(np.asarray(axis) / np.linalg.norm(axis) * (np.pi - epsilon))
    pose = pose_from_matrix(transform(rotation.as_matrix(), [0, 0, 0]))
    assert pose[3] >= 0 and pose[3] < 1e-4
    assert np.linalg.norm(pose[3:]) == pytest.approx(1, abs=1e-6)
    np.testing.assert_allclose(matrix_of(pose), rotation.as_matrix(), atol=1e-5)


@settings(max_examples=200, deadline=None)
@given(unit_quats, st.lists(st.floats(-2e-3, 2e-3), min_size=9, max_size=9), st.floats(0.97, 1.03))
def test_drifted_matrices_become_the_nearest_rotation(quat_xyzw, noise, scale):
    drifted = Rotation.from_quat(quat_xyzw).as_matrix() * scale + np.reshape(noise, (3, 3))
    u, _, vt = np.linalg.svd(drifted)
    nearest = u @ vt  # the orthogonal polar factor: the closest rotation in the Frobenius norm
    pose = pose_from_matrix(transform(drifted, [1, 2, 3]))
    np.testing.assert_allclose(matrix_of(pose), nearest, atol=1e-5)


@pytest.mark.parametrize("rotation", [
    np.full((3, 3), np.nan), np.diag([np.inf] * 3), np.zeros((3, 3)), np.diag([1.0, 1.0, -1.0]),
    np.ones((3, 3)),
])
def test_broken_matrices_give_no_pose(rotation):
    assert pose_from_matrix(transform(rotation, [0, 0, 0])) is None
    assert pose_from_matrix(transform(np.eye(3), [0, np.nan, 0])) is None
    assert pose_from_matrix(transform(np.eye(3), [1e39, 0, 0])) is None  # overflows float32


def test_pose_array_to_roles():
    half_turn = transform(np.diag([-1.0, -1.0, 1.0]), [0.1, 1.2, -0.3])
    identity = transform(np.eye(3), [0.0, 1.5, 0.0])
    poses = [Pose(True, identity),       # 0: headset-like, not a tracker
             Pose(True, half_turn),      # 1: chest tracker
             Pose(False, identity),      # 2: left wrist, tracking lost
             Pose(True, identity),       # 3: a tracker with no role
             Pose(True, transform(np.zeros((3, 3)), [0, 0, 0]))]  # 4: right wrist, broken matrix
    serials = {1: "LHR-CHEST", 2: "LHR-LEFT", 3: "LHR-SPARE", 4: "LHR-RIGHT", 9: "LHR-GONE"}
    roles = {"LHR-CHEST": "chest", "LHR-LEFT": "left_wrist", "LHR-RIGHT": "right_wrist"}
    by_role, unknown = poses_by_role(poses, serials, roles)
    assert set(by_role) == {"chest"} and unknown == {"LHR-SPARE"}
    np.testing.assert_allclose(by_role["chest"], [0.1, 1.2, -0.3, 0, 0, 0, 1], atol=1e-7)
    assert by_role["chest"].dtype == np.float32
    assert poses_by_role([], serials, roles) == ({}, set())


@pytest.mark.parametrize("options, message", [
    ({"roles": {}}, "no Vive trackers configured"),
    ({"roles": {"LHR-1": "head"}}, "unknown tracker role"),
    ({"roles": {"LHR-1": "chest", "LHR-2": "chest"}}, "same role"),
    ({"roles": {"LHR-1": "chest"}, "rate_hz": 0}, "rate must be a positive"),
])
def test_bad_tracker_options_are_user_errors(options, message):
    with pytest.raises(UserError, match=message):
        OpenVRTrackersConfig(**options)


@pytest.mark.skipif(importlib.util.find_spec("openvr") is not None, reason="openvr is installed here")
def test_connect_without_openvr_says_how_to_install_it():
    trackers = OpenVRTrackers(OpenVRTrackersConfig({"LHR-1": "chest", "LHR-2": "left_wrist"}))
    with pytest.raises(UserError) as error:
        trackers.connect()
    assert str(error.value) == INSTALL_HINT
    assert str(error.value) == "OpenVR trackers need the `openvr` package: .venv/bin/pip install -e '.[trackers]' in the checkout"
    assert not trackers.is_connected and trackers.status() == "disconnected" and trackers.latest() is None
    assert not [t for t in threading.enumerate() if t.name.endswith(" reader")]


class SteamVR:
    """Stand-in for the `openvr` module and the SteamVR behind it (no OpenVR runtime exists here), built on
    the `Pose` double above: one generic tracker "LHR-CHEST" at `tracker_index`; `quit()` announces a quit
    (VREvent_Quit) and stops, `crash()` stops without a word (calls raise OpenVRError), `start()` runs again
    (the tracker may come back at another device index)."""

    VRApplication_Other, TrackingUniverseStanding, k_unMaxTrackedDeviceCount = 3, 1, 16
    TrackedDeviceClass_GenericTracker, Prop_SerialNumber_String, VREvent_Quit = 3, 1002, 700

    class OpenVRError(Exception):
        pass

    class VREvent_t:
        eventType = 0

    def __init__(self) -> None:
        self.running, self.events, self.tracker_index = True, [], 2
        self.inits = self.shutdowns = self.acknowledged = 0

    def init(self, kind: int) -> SteamVR:
        assert kind == self.VRApplication_Other
        if not self.running:
            raise self.OpenVRError("VRInitError_Init_NoServerForBackgroundApp")
        self.inits += 1
        return self

    def shutdown(self) -> None:
        self.shutdowns += 1

    def pollNextEvent(self, event) -> bool:  # noqa: N802 - OpenVR's names
        if not self.events:
            return False
        event.eventType = self.events.pop(0)
        return True

    def acknowledgeQuit_Exiting(self) -> None:  # noqa: N802
        self.acknowledged += 1

    def getDeviceToAbsoluteTrackingPose(self, universe: int, predict: float, count: int) -> list[Pose]:  # noqa: N802
        if not self.running:
            raise self.OpenVRError("IPC failed: vrserver is gone")
        poses = [Pose(False, transform(np.eye(3), [0, 0, 0])) for _ in range(count)]
        poses[self.tracker_index] = Pose(True, transform(np.eye(3), [0.0, 1.2, float(self.tracker_index)]))
        return poses

    def getTrackedDeviceClass(self, index: int) -> int:  # noqa: N802
        return self.TrackedDeviceClass_GenericTracker if index == self.tracker_index else 0

    def getStringTrackedDeviceProperty(self, index: int, prop: int) -> str:  # noqa: N802
        return "LHR-CHEST"

    def quit(self) -> None:
        self.events.append(self.VREvent_Quit)
        self.running = False

    def crash(self) -> None:
        self.running = False

    def start(self, tracker_index: int) -> None:
        self.tracker_index, self.running = tracker_index, True


def wait_for(predicate, what: str, timeout: float = 5.0):
    deadline = time.monotonic() + timeout
    while not (result := predicate()):
        assert time.monotonic() < deadline, f"{what} did not happen within {timeout} s"
        time.sleep(0.005)
    return result


def chest_at(trackers: OpenVRTrackers, z: float) -> bool:
    reading = trackers.latest()
    return reading is not None and "chest" in reading.poses and reading.poses["chest"][2] == z


def test_trackers_retry_while_steamvr_is_away_and_find_their_roles_again(monkeypatch):
    steamvr = SteamVR()
    monkeypatch.setitem(sys.modules, "openvr", steamvr)
    trackers = OpenVRTrackers(OpenVRTrackersConfig({"LHR-CHEST": "chest"}, rate_hz=200, reconnect_backoff_s=(0.05, 0.3)))
    with trackers:
        wait_for(lambda: chest_at(trackers, 2.0), "the chest pose")
        for stop, reason in ((steamvr.quit, "SteamVR quit"), (steamvr.crash, "OpenVR failed: IPC failed: vrserver is gone")):
            reconnects = trackers.counters.reconnects
            stop()
            status = wait_for(lambda: (s := trackers.status()).startswith("disconnected, retrying (") and s, "retrying")
            assert status.startswith(f"disconnected, retrying ({reason}) every ≤ 0.3 s, ")
            assert trackers.is_connected and steamvr.shutdowns == steamvr.inits  # OpenVR was shut down
            wait_for(lambda: "OpenVR could not start" in (trackers.down_reason or ""), "a failed reopen")
            assert "VRInitError_Init_NoServerForBackgroundApp" in trackers.down_reason
            time.sleep(0.4)
            index = steamvr.tracker_index + 3
            steamvr.start(index)  # SteamVR is back; the tracker has another device index now
            wait_for(lambda: chest_at(trackers, float(index)), "the chest pose after the return", timeout=1.5)
            assert trackers.counters.reconnects == reconnects + 1 and not trackers.retrying
        assert steamvr.acknowledged == 1 and trackers.status().startswith("connected, ")
    assert steamvr.shutdowns == steamvr.inits == 3 and trackers.counters.errors == 0
    assert not [t for t in threading.enumerate() if t.name.endswith(" reader")]
