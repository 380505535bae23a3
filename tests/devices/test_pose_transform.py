"""Mocap joints → the model's frame (head camera, WiLoR convention): against a simulated episode where the
truth is known, exactly against the simulated rig's own chain, rigid-motion invariance, bad input, and the
`[pose]` calibration's dict/TOML round trip and error messages."""
from __future__ import annotations

import json
import tomllib
import warnings
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from touchanything.core.errors import UserError
from touchanything.core.snapshot import TRACKER_ROLES
from touchanything.devices.episodes.episode_streams import read_hands, read_trackers
from touchanything.devices.rig.pose_transform import (
    BAD_CHEST,
    NO_CHEST,
    NOT_FINITE,
    NOT_TRACKED,
    OUT_OF_BOUNDS,
    PoseCalibration,
    mocap_to_model_frame,
    wilor_from_camera,
)
from touchanything.devices.sim.cameras import HEAD_FOCAL, HEIGHT, WIDTH, Camera
from touchanything.devices.sim.episode_generator import EpisodeSpec, generate_episode
from touchanything.devices.sim.pose_estimate import DEPTH_JITTER, JITTER
from touchanything.devices.sim.rig import ROKOKO_AXES, rig_calibration, rokoko_joints, tracker_poses
from touchanything.devices.sim.shapes import pose_at, transform
from touchanything.viz.hand_projection import project_wilor

FAST = settings(max_examples=40, deadline=None)
CALIBRATION = rig_calibration()
NOISE = JITTER
"""WiLoR's per-frame jitter per coordinate in the simulator (the smooth estimation error is in both streams)."""
DEPTH_NOISE = DEPTH_JITTER
"""WiLoR's per-frame wrist-depth jitter in the simulator, relative."""


@pytest.fixture(scope="module")
def episode(tmp_path_factory) -> dict:
    """A 2 s simulated episode's Rokoko, WiLoR and Vive streams as written to disk."""
    stats = generate_episode(tmp_path_factory.mktemp("sim"), EpisodeSpec("Home", 2.0, 11, False, "ep"))
    rokoko, _ = read_hands(stats.folder / "rokoko_hands.json")
    wilor, _ = read_hands(stats.folder / "wilor_hands.json")
    trackers, _ = read_trackers(stats.folder / "vive_poses.json")
    return {"rokoko": rokoko, "wilor": wilor, "trackers": trackers}


def _episode_in_model_frame(episode: dict, calibration: PoseCalibration) -> tuple[np.ndarray, np.ndarray]:
    rokoko, trackers = episode["rokoko"], episode["trackers"]
    results = []
    for k in range(len(rokoko.valid)):
        poses = {role: trackers.poses[k, r] for r, role in enumerate(TRACKER_ROLES) if trackers.valid[k, r]}
        results.append(mocap_to_model_frame(rokoko.joints[k], rokoko.valid[k], poses, calibration))
    return np.stack([r.joints for r in results]), np.stack([r.valid for r in results])


def _mismatch(episode: dict, calibration: PoseCalibration) -> list[str]:
    """Where the transformed mocap disagrees with the episode's WiLoR joints beyond the simulator's noise.

    The WiLoR stream carries estimator noise (σ = 3 mm per coordinate, 2 % on the wrist depth), so the
    comparison is statistical: the hand shape relative to the wrist and the wrist's x, y must agree to within
    that noise (RMS and a 5σ maximum, no bias), the wrist depth to within the 2 % depth noise.
    """
    ours, valid = _episode_in_model_frame(episode, calibration)
    wilor = episode["wilor"]
    both = valid & wilor.valid
    assert both.sum(axis=0).min() >= 20, "too few frames with both hands valid to compare"
    a, b = ours[both].astype(np.float64), wilor.joints[both].astype(np.float64)
    shape = (a[:, 1:] - a[:, :1]) - (b[:, 1:] - b[:, :1])
    wrist_xy = a[:, 0, :2] - b[:, 0, :2]
    depth_ratio = b[:, 0, 2] / a[:, 0, 2]
    problems = []
    if np.sqrt(np.mean(shape ** 2)) > 1.5 * np.sqrt(2) * NOISE or np.abs(shape).max() > 5 * np.sqrt(2) * NOISE:
        problems.append("hand shape")
    if np.abs(shape.mean(axis=(0, 1))).max() > NOISE / 2:
        problems.append("hand shape bias")
    if np.sqrt(np.mean(wrist_xy ** 2)) > 1.5 * NOISE or np.abs(wrist_xy).max() > 5 * NOISE:
        problems.append("wrist x, y")
    if np.abs(depth_ratio - 1).max() > 5 * DEPTH_NOISE or abs(depth_ratio.mean() - 1) > DEPTH_NOISE / 2:
        problems.append("wrist depth")
    return problems


def test_simulated_mocap_reproduces_the_episodes_wilor_joints(episode):
    assert _mismatch(episode, CALIBRATION) == []


def test_a_two_degree_mount_error_is_detected(episode):
    """The comparison above is sharp enough to see a chest→camera mount off by 2° (1° is also seen, 0.5° not)."""
    tilted = Rotation.from_euler("x", 2.0, degrees=True) * _rotation(CALIBRATION.camera_in_chest_wxyz)
    wrong = replace(CALIBRATION, camera_in_chest_wxyz=tuple(tilted.as_quat(scalar_first=True).tolist()))
    assert _mismatch(episode, wrong) != []


def _rotation(wxyz) -> Rotation:
    return Rotation.from_quat(wxyz, scalar_first=True)


def _camera(seed: int, position: np.ndarray) -> Camera:
    pose = pose_at(position, Rotation.random(random_state=seed).as_matrix())
    return Camera("chest", pose, "pinhole", HEAD_FOCAL)


def _hands_in_front(seed: int) -> np.ndarray:
    """(2, 21, 3) points in the camera frame, 0.2–2 m in front and within the view."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.2, 2.0, size=(2, 21, 1))
    return np.concatenate([rng.uniform(-0.8, 0.8, size=(2, 21, 2)) * z, z], axis=-1)


seeds = st.integers(0, 2**32 - 1)
positions = st.lists(st.floats(-3, 3), min_size=3, max_size=3).map(np.array)


@FAST
@given(seeds, positions, seeds)
def test_the_simulated_rigs_chain_is_inverted_exactly(camera_seed, position, hands_seed):
    """Rokoko joints and tracker poses as the simulator makes them (float32), with its calibration, give
    the head-camera joints in the WiLoR convention to within float32 rounding."""
    camera = _camera(camera_seed, position)
    in_camera = _hands_in_front(hands_seed)
    world = transform(camera.pose, in_camera)
    poses = tracker_poses(camera.pose, np.stack([np.eye(4), np.eye(4)]))
    result = mocap_to_model_frame(rokoko_joints(world), np.ones(2, bool), dict(zip(TRACKER_ROLES, poses)), CALIBRATION)
    assert result.valid.all() and result.reasons == ("", "")
    np.testing.assert_allclose(result.joints, wilor_from_camera(in_camera, CALIBRATION.depth_scale), atol=1e-4)


def test_the_wilor_convention_keeps_the_wrist_pixel_and_the_metric_hand_shape():
    camera = _camera(3, np.zeros(3))
    in_camera = _hands_in_front(4)
    model = wilor_from_camera(in_camera, CALIBRATION.depth_scale)
    real_pixels, _, _ = camera.project(transform(camera.pose, in_camera[:, 0]))
    np.testing.assert_allclose(project_wilor(model[:, 0], WIDTH, HEIGHT), real_pixels, atol=1e-6)
    np.testing.assert_allclose(model - model[:, :1], in_camera - in_camera[:, :1], atol=1e-12)
    assert np.all(model[:, 0, 2] > 30 * in_camera[:, 0, 2])  # 5000/256·640 px against 320 px: depth × 39


def _scene(seed: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """float64 mocap joints and tracker poses of a simulated rig with the camera somewhere in the room."""
    camera = _camera(seed, np.random.default_rng(seed).uniform(-2, 2, 3))
    world = transform(camera.pose, _hands_in_front(seed))
    poses = tracker_poses(camera.pose, np.stack([np.eye(4), np.eye(4)])).astype(np.float64)
    return world[..., list(ROKOKO_AXES)], dict(zip(TRACKER_ROLES, poses))


def _moved_pose(motion: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """A (7,) trans + wxyz pose moved by the 4×4 rigid `motion`."""
    rotation = Rotation.from_matrix(motion[:3, :3])
    turned = rotation * _rotation(pose[3:])
    return np.concatenate([rotation.apply(pose[:3]) + motion[:3, 3], turned.as_quat(scalar_first=True)])


def _rigid(seed: int, shift: np.ndarray) -> np.ndarray:
    return pose_at(shift, Rotation.random(random_state=seed).as_matrix())


@FAST
@given(seeds, seeds, positions)
def test_moving_the_whole_rig_leaves_the_model_frame_joints_unchanged(scene_seed, motion_seed, shift):
    """The person walks and turns: every tracker and every mocap joint moves by the same rigid motion."""
    mocap, trackers = _scene(scene_seed)
    motion = _rigid(motion_seed, shift)
    matrix = np.asarray(CALIBRATION.tracking_from_mocap)
    mocap_to_tracking = np.vstack([matrix, [0, 0, 0, 1]])
    moved_mocap = transform(np.linalg.inv(mocap_to_tracking) @ motion @ mocap_to_tracking, mocap)
    moved_trackers = {role: _moved_pose(motion, pose) for role, pose in trackers.items()}
    before = mocap_to_model_frame(mocap, np.ones(2, bool), trackers, CALIBRATION)
    after = mocap_to_model_frame(moved_mocap, np.ones(2, bool), moved_trackers, CALIBRATION)
    assert before.valid.all() and after.valid.all()
    np.testing.assert_allclose(after.joints, before.joints, atol=1e-4)


@FAST
@given(seeds, seeds, positions)
def test_a_new_tracking_origin_with_its_calibration_leaves_the_joints_unchanged(scene_seed, motion_seed, shift):
    """SteamVR's room setup moved the universe: trackers and tracking_from_mocap change together."""
    mocap, trackers = _scene(scene_seed)
    motion = _rigid(motion_seed, shift)
    matrix = motion @ np.vstack([np.asarray(CALIBRATION.tracking_from_mocap), [0, 0, 0, 1]])
    recalibrated = replace(CALIBRATION, tracking_from_mocap=tuple(map(tuple, matrix[:3].tolist())))
    moved_trackers = {role: _moved_pose(motion, pose) for role, pose in trackers.items()}
    before = mocap_to_model_frame(mocap, np.ones(2, bool), trackers, CALIBRATION)
    after = mocap_to_model_frame(mocap, np.ones(2, bool), moved_trackers, recalibrated)
    np.testing.assert_allclose(after.joints, before.joints, atol=1e-4)


bad_values = st.sampled_from([np.nan, np.inf, -np.inf])


@FAST
@given(seeds, st.integers(0, 1), st.integers(0, 20), st.integers(0, 2), bad_values)
def test_a_non_finite_joint_makes_only_its_hand_invalid(seed, hand, joint, axis, value):
    mocap, trackers = _scene(seed)
    baseline = mocap_to_model_frame(mocap, np.ones(2, bool), trackers, CALIBRATION)
    mocap[hand, joint, axis] = value
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = mocap_to_model_frame(mocap, np.ones(2, bool), trackers, CALIBRATION)
    other = 1 - hand
    assert not result.valid[hand] and result.reasons[hand] == NOT_FINITE and not result.joints[hand].any()
    assert result.valid[other] and result.reasons[other] == ""
    np.testing.assert_array_equal(result.joints[other], baseline.joints[other])


@FAST
@given(seeds, st.integers(0, 6), bad_values)
def test_a_non_finite_chest_pose_makes_both_hands_invalid(seed, index, value):
    mocap, trackers = _scene(seed)
    trackers["chest"][index] = value
    result = mocap_to_model_frame(mocap, np.ones(2, bool), trackers, CALIBRATION)
    assert not result.valid.any() and result.reasons == (BAD_CHEST, BAD_CHEST) and not result.joints.any()


def test_without_a_chest_tracker_both_hands_are_invalid_with_the_reason():
    mocap, trackers = _scene(1)
    del trackers["chest"]
    result = mocap_to_model_frame(mocap, np.ones(2, bool), trackers, CALIBRATION)
    assert not result.valid.any() and result.reasons == (NO_CHEST, NO_CHEST)
    assert result.joints.shape == (2, 21, 3) and result.joints.dtype == np.float32 and not result.joints.any()
    zero_quaternion = {**trackers, "chest": np.zeros(7)}
    assert mocap_to_model_frame(mocap, np.ones(2, bool), zero_quaternion, CALIBRATION).reasons == (BAD_CHEST, BAD_CHEST)


def test_a_hand_the_mocap_does_not_track_is_invalid():
    mocap, trackers = _scene(2)
    result = mocap_to_model_frame(mocap, np.array([True, False]), trackers, CALIBRATION)
    assert result.valid.tolist() == [True, False] and result.reasons == ("", NOT_TRACKED)


def _mocap_for_camera_points(in_camera: np.ndarray, trackers: dict[str, np.ndarray]) -> np.ndarray:
    """Mocap joints of points given in the head camera's frame (inverting the calibration chain)."""
    chest = trackers["chest"]
    camera = _rotation(chest[3:]) * _rotation(CALIBRATION.camera_in_chest_wxyz)
    origin = chest[:3] + _rotation(chest[3:]).apply(CALIBRATION.camera_in_chest_trans)
    tracking = camera.apply(in_camera.reshape(-1, 3)) + origin
    matrix = np.asarray(CALIBRATION.tracking_from_mocap)
    return ((tracking - matrix[:, 3]) @ matrix[:, :3]).reshape(in_camera.shape)


def test_behind_the_camera_is_kept_and_too_far_is_out_of_bounds():
    """The official rule has no lower bound on z: a hand behind the camera stays valid (negative z); one
    30 m away lands beyond z = 1000 in WiLoR units and is invalid. Huge values raise no warnings."""
    _, trackers = _scene(5)
    in_camera = _hands_in_front(6)
    in_camera[0, :, 2] *= -1
    in_camera[1] += [0.0, 0.0, 30.0]
    mocap = _mocap_for_camera_points(in_camera, trackers)
    result = mocap_to_model_frame(mocap, np.ones(2, bool), trackers, CALIBRATION)
    assert result.valid.tolist() == [True, False] and result.reasons == ("", OUT_OF_BOUNDS)
    assert result.joints[0, 0, 2] < 0
    huge = np.full((2, 21, 3), 1e300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = mocap_to_model_frame(huge, np.ones(2, bool), trackers, CALIBRATION)
    assert result.reasons == (OUT_OF_BOUNDS, OUT_OF_BOUNDS)


finite = st.floats(-10, 10, allow_nan=False)


@st.composite
def calibrations(draw) -> PoseCalibration:
    rotation = Rotation.random(random_state=draw(seeds)).as_matrix() * np.array([1, 1, draw(st.sampled_from([1, -1]))])
    matrix = np.hstack([rotation, np.array(draw(st.lists(finite, min_size=3, max_size=3)))[:, None]])
    return PoseCalibration(
        tracking_from_mocap=tuple(map(tuple, matrix.tolist())),
        camera_in_chest_trans=tuple(draw(st.lists(finite, min_size=3, max_size=3))),
        camera_in_chest_wxyz=tuple(Rotation.random(random_state=draw(seeds)).as_quat(scalar_first=True).tolist()),
        image_size=(draw(st.integers(1, 8192)), draw(st.integers(1, 8192))),
        focal_px=draw(st.floats(1e-3, 1e5)),
    )


def _toml(section: dict) -> str:
    """A `[pose]` TOML table: JSON arrays and numbers are valid TOML values."""
    return "[pose]\n" + "".join(f"{key} = {json.dumps(value)}\n" for key, value in section.items())


@FAST
@given(calibrations())
def test_calibration_round_trips_through_a_dict_and_a_toml_section(calibration):
    assert PoseCalibration.from_dict(calibration.to_dict()) == calibration
    assert PoseCalibration.from_dict(tomllib.loads(_toml(calibration.to_dict()))["pose"]) == calibration


def test_the_simulated_rigs_calibration_is_a_valid_toml_section():
    section = tomllib.loads(_toml(CALIBRATION.to_dict()))["pose"]
    assert PoseCalibration.from_dict(section) == CALIBRATION
    assert np.linalg.det(np.asarray(CALIBRATION.tracking_from_mocap)[:, :3]) == pytest.approx(-1)


GOOD = CALIBRATION.to_dict()
MISSING = object()


@pytest.mark.parametrize("change, key", [
    ({"focal": 300.0}, "'focal'"),
    ({"focal_px": MISSING}, "focal_px"),
    ({"focal_px": -5.0}, "focal_px"),
    ({"focal_px": True}, "focal_px"),
    ({"focal_px": "320"}, "focal_px"),
    ({"image_size": [640]}, "image_size"),
    ({"image_size": [640.0, 480.0]}, "image_size"),
    ({"image_size": [0, 480]}, "image_size"),
    ({"image_size": 640}, "image_size"),
    ({"camera_in_chest_trans": [0.0, 0.1]}, "camera_in_chest_trans"),
    ({"camera_in_chest_trans": [0.0, float("nan"), 0.0]}, "camera_in_chest_trans"),
    ({"camera_in_chest_wxyz": [0.0, 0.0, 0.0, 0.0]}, "camera_in_chest_wxyz"),
    ({"camera_in_chest_wxyz": [1.0, 0.0, "0", 0.0]}, "camera_in_chest_wxyz"),
    ({"tracking_from_mocap": [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]}, "tracking_from_mocap"),
    ({"tracking_from_mocap": [[2.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0]]}, "tracking_from_mocap"),
    ({"tracking_from_mocap": [[1.0, 0, 0, float("inf")], [0, 1.0, 0, 0], [0, 0, 1.0, 0]]}, "tracking_from_mocap"),
    ({"tracking_from_mocap": 1.0}, "tracking_from_mocap"),
])
def test_bad_calibration_names_the_key_in_one_line(change, key):
    section = {name: value for name, value in {**GOOD, **change}.items() if value is not MISSING}
    with pytest.raises(UserError) as error:
        PoseCalibration.from_dict(section)
    message = str(error.value)
    assert key in message and "\n" not in message and message.startswith("[pose]")


def test_a_pose_section_that_is_not_a_table_is_refused():
    with pytest.raises(UserError, match=r"^\[pose\] must be a table"):
        PoseCalibration.from_dict([1.0, 2.0])
