"""Vive trackers through OpenVR: matrix → (trans, quaternion w,x,y,z), pose arrays → roles, options, and the
user error when the optional `openvr` package is not installed (it is not, here)."""
from __future__ import annotations

import importlib.util
import threading
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from touchanything.devices.errors import UserError
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
    assert str(error.value) == "OpenVR trackers need the `openvr` package: pip install 'touchanything[trackers]'"
    assert not trackers.is_connected and trackers.status() == "disconnected" and trackers.latest() is None
    assert not [t for t in threading.enumerate() if t.name.endswith(" reader")]
