"""The hand-pose estimator with MediaPipe on real images (../shared/reference/hands), and everything built on it:
a plain video replayed end to end headless and in the dashboard, `pose` writing a WiLoR file the episode
reader takes, a webcam scene (a video file standing in for the camera) live, and the user errors."""
from __future__ import annotations

import contextlib
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers.hand_video import HANDS_DIR, background, reference_image, write_hand_video
from touchanything.app.cli import main
from touchanything.app.sessions.engine_choice import build_engine, choose, default_checkpoint
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.core.errors import UserError
from touchanything.core.hand_pose import pose_is_valid
from touchanything.core.snapshot import POSE_FROM_CAMERA
from touchanything.devices.camera_pose.estimator import STAGE, CameraPoseConfig, HandPoseEstimator
from touchanything.devices.camera_pose.model_file import installed_model_path
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.raw_episode import open_raw_episode
from touchanything.devices.episodes.video_io import VideoReader, VideoWriter
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.viz.replay_frame import footer_text

NANO = choose(default_checkpoint())
FRAMES, EMPTY = 24, 4


@pytest.fixture(scope="module", autouse=True)
def needs_model_and_images():
    if not installed_model_path().is_file():
        pytest.skip(f"{installed_model_path()} is not built (make hand-model)")
    if not HANDS_DIR.is_dir():
        pytest.skip("../shared/reference/hands is not beside the checkout")


@pytest.fixture(scope="module")
def estimator():
    with HandPoseEstimator(CameraPoseConfig(smoothing=0.0)) as estimator:
        yield estimator


@pytest.fixture(scope="module")
def hand_video(tmp_path_factory) -> Path:
    return write_hand_video(tmp_path_factory.mktemp("video") / "hands.mp4", FRAMES, EMPTY)


def one_frame(estimator: HandPoseEstimator, image: np.ndarray):
    estimator.reset()
    return estimator.estimate(np.ascontiguousarray(image), 0)


def check_hand(joints: np.ndarray, depth: tuple[float, float]) -> None:
    """A plausible hand in WiLoR's camera frame: the official bounds, in front at `depth`, hand-sized."""
    assert pose_is_valid(joints)
    assert depth[0] < joints[0, 2] < depth[1], joints[0]
    palm = np.linalg.norm(joints[9] - joints[0])  # wrist to middle-finger knuckle, metres
    assert 0.06 < palm < 0.14, palm


# --- the estimator on the reference images ---------------------------------------------------------------------


def test_both_hands_of_the_person_in_the_room(estimator):
    """two_hands_room.jpg, unmirrored: the person's right hand raised at the image's left, the left hand low
    at its right. At 1280×720 the hands are ~35 px and the palm detector (192×192 input) does not find them
    at MediaPipe's default thresholds; the left half of the image (640×720, the person) is used."""
    image = reference_image("two_hands_room.jpg")[:, :640]
    found = one_frame(estimator, image)
    assert found.valid.tolist() == [True, True], found.confidence
    joints = found.joints.reshape(2, 21, 3)
    for hand in joints:
        check_hand(hand, (15.0, 80.0))  # a person about 3 m away, depth stretched by WiLoR's focal length
    assert joints[0, 0, 0] > 0 > joints[1, 0, 0]  # left hand right of the image centre, right hand left of it
    assert joints[1, 0, 1] < joints[0, 0, 1]  # the raised right hand is higher (y down)
    assert np.all(found.reprojection_px < 6), found.reprojection_px
    assert np.all((found.confidence > 0.3) & (found.confidence <= 1))


def test_a_hand_in_a_frame_and_its_mirror_image(estimator):
    frame = background()
    frame[128:352, 208:432] = reference_image("hand0.jpg")
    right = one_frame(estimator, frame)
    assert right.valid.tolist() == [False, True] and right.confidence[1] > 0.8
    check_hand(right.joints.reshape(2, 21, 3)[1], (6.0, 25.0))
    assert not right.joints[:21].any() and right.confidence[0] == 0 and np.isnan(right.reprojection_px[0])
    mirrored = one_frame(estimator, frame[:, ::-1])
    assert mirrored.valid.tolist() == [True, False]
    np.testing.assert_allclose(mirrored.joints[0, 2], right.joints[21, 2], rtol=0.05)  # same depth
    with HandPoseEstimator(CameraPoseConfig(mirror=True, smoothing=0.0)) as selfie:
        assert selfie.estimate(frame, 0).valid.tolist() == [True, False]


def test_no_hand_is_no_valid_pose(estimator):
    found = one_frame(estimator, background())
    assert found.valid.tolist() == [False, False] and not found.joints.any() and found.ms > 0


# --- a plain video replayed ---------------------------------------------------------------------------------


def camera_replay(path: Path, **config) -> ReplaySource:
    return ReplaySource(open_episode(path), ReplayConfig(speed=None, pose_source="camera", **config))


def test_replay_estimates_the_same_poses_every_time_and_restarts_at_a_seek(hand_video):
    runs = []
    for _ in range(2):
        with contextlib.closing(camera_replay(hand_video)) as source:
            runs.append([(s.joints.copy(), s.joints_valid.copy()) for s in source])
    assert len(runs[0]) == FRAMES
    for (a, va), (b, vb) in zip(*runs):
        assert np.array_equal(a, b) and np.array_equal(va, vb)
    valid = np.array([v for _, v in runs[0]])
    assert not valid[:EMPTY].any() and valid[EMPTY + 2:].all()
    with contextlib.closing(camera_replay(hand_video)) as seeking, contextlib.closing(camera_replay(hand_video)) as fresh:
        for k in range(15):
            seeking.snapshot(k)
        back = [seeking.snapshot(k).joints for k in (8, 9)]
        again = [fresh.snapshot(k).joints for k in (8, 9)]
    assert np.array_equal(back[0], again[0]) and np.array_equal(back[1], again[1])


def test_no_camera_hand_no_prediction_with_the_reason_shown(hand_video):
    engine = build_engine(NANO)
    with contextlib.closing(camera_replay(hand_video)) as source:
        for snapshot in source:
            [prediction] = engine.step(snapshot)
            footer = footer_text(snapshot, FRAMES, prediction, None)
            assert snapshot.pose_source == POSE_FROM_CAMERA and STAGE in snapshot.stage_ms
            if snapshot.frame_index < EMPTY:
                assert prediction.hands_predicted == (False, False) and prediction.status == "no valid hand pose"
                assert "pose: camera estimate (left not found, right not found)" in footer
                assert "no valid hand pose" in footer and snapshot.source_status["pose"] == "camera: no hand found"
            elif snapshot.frame_index > EMPTY + 2:
                assert prediction.hands_predicted == (True, True) and prediction.status == "ok"
                assert np.nanmax(prediction.pressure) <= 1 and "pose: camera estimate (left 0." in footer


def test_replay_of_a_plain_video_headless(hand_video, tmp_path, capsys):
    out = tmp_path / "replay.mp4"
    assert main(["replay", str(hand_video), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"episode   plain video  ({hand_video})" in printed
    assert "metrics   n/a (the episode has no ground-truth pressure)" in printed
    frames_line = next(line for line in printed.splitlines() if line.startswith("frames    24 written"))
    assert EMPTY <= int(frames_line.split(", ")[-1].split()[0]) <= EMPTY + 2, frames_line
    assert frames_line.endswith(" without a hand pose (nothing predicted)")
    line = next(line for line in printed.splitlines() if line.startswith("poses"))
    counts = [int(n) for n in line.split(":", 1)[1].replace(",", " ").split() if n.isdigit()][:3]
    assert line.startswith("poses     camera estimate: ") and counts[2] == FRAMES
    assert counts[0] >= FRAMES - EMPTY - 2 and counts[1] >= FRAMES - EMPTY - 2, line
    assert " ms per frame (p99 " in line
    model_line = next(line for line in printed.splitlines() if line.startswith("model     "))
    assert "— trained on simulated data (torch-fp32 on cpu), " in model_line and "; held-out V-IoU " in model_line, model_line
    assert "note      illustrative only: bare-hand poses from the camera" in printed
    with VideoReader(out) as video:
        assert video.num_frames == FRAMES and video.read(FRAMES - 1).shape == (806, 1440, 3)


def test_the_dashboard_says_a_camera_pose_prediction_is_illustrative(hand_video):
    choice = choose(default_checkpoint())
    with open_episode(hand_video) as episode:
        session = ReplaySession(episode, build_engine(choice), choice, pose_source="camera").start()
        try:
            deadline = time.monotonic() + 60
            while session.state().snapshot is None and time.monotonic() < deadline:
                time.sleep(0.05)
            model = session.state().model
        finally:
            session.close()
    assert model.startswith("pico — trained on simulated data") and model.endswith(
        " — illustrative only: bare-hand poses from the camera, model trained on simulated gloved hands"), model


# --- poses to a WiLoR file ----------------------------------------------------------------------------------------


def test_pose_writes_a_wilor_file_the_episode_reader_takes(hand_video, tmp_path, capsys):
    folder = tmp_path / "Home" / "wave" / "001"
    folder.mkdir(parents=True)
    shutil.copy(hand_video, folder / "chest.mp4")
    out = folder / "wilor_hands.json"
    assert main(["pose", str(folder / "chest.mp4"), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "100%" in captured.err and f"wrote     {out}" in captured.out and "poses     camera estimate" in captured.out
    assert "no hand" not in captured.out
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [row["frame_index"] for row in rows] == list(range(FRAMES))
    assert rows[0]["left_pos"] == [] and len(rows[-1]["right_pos"]) == 21
    with open_raw_episode(folder) as episode:
        assert episode.wilor is not None and not [p for p in episode.problems if "wilor_hands.json" in p]
        with contextlib.closing(camera_replay(hand_video)) as source:
            estimated = [(s.joints.reshape(2, 21, 3), s.joints_valid) for s in source]
        assert np.array_equal(episode.wilor.valid, np.array([v for _, v in estimated]))
        np.testing.assert_allclose(episode.wilor.joints, np.array([j for j, _ in estimated]), atol=1e-6)
    assert main(["pose", str(folder / "chest.mp4"), "--out", str(out)]) == 2
    assert capsys.readouterr().err == f"touchanything pose: error: {out}: exists; pass --overwrite to replace it\n"


# --- user errors: one line each --------------------------------------------------------------------------------


def one_line_error(argv: list[str], capsys) -> str:
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1, captured.err
    return captured.err


def test_bad_videos_and_a_missing_model_are_one_line(tmp_path, capsys, hand_video):
    junk = tmp_path / "junk.mp4"
    junk.write_text("not a video")
    assert "nope.mp4: not found" in one_line_error(["replay", str(tmp_path / "nope.mp4"), "--out", str(tmp_path / "o.mp4")], capsys)
    assert "junk.mp4: not an episode folder or .hdf5 file, and not a video PyAV can read: unreadable video" in \
        one_line_error(["replay", str(junk), "--headless"], capsys)
    assert "junk.mp4: not a video PyAV can read: unreadable video" in \
        one_line_error(["pose", str(junk), "--out", str(tmp_path / "w.json")], capsys)
    assert "a folder; pass a video file" in one_line_error(["pose", str(tmp_path), "--out", str(tmp_path / "w.json")], capsys)
    missing = tmp_path / "missing.task"
    with pytest.raises(UserError, match="hand model file not found; build it with `make hand-model"):
        camera_replay(hand_video, camera_pose=CameraPoseConfig(model=missing))


# --- a webcam scene, live --------------------------------------------------------------------------------------


def test_a_webcam_scene_estimates_the_hands_live(hand_video, tmp_path, capsys):
    """scenes/webcam.toml with its camera replaced by the hands video (looping, paced like a camera)."""
    text = (Path(__file__).resolve().parents[2] / "scenes" / "webcam.toml").read_text()
    scene = tmp_path / "webcam.toml"
    scene.write_text(text.replace("source = 0 ", f'source = "{hand_video}"\nloop = true ', 1))
    assert main(["live", "--scene", str(scene), "--headless", "--seconds", "4"]) == 0
    printed = capsys.readouterr().out
    assert "camera hands: ok" in printed and "pose: camera estimate (left 0." in printed, printed
    summary = next(line for line in printed.splitlines() if line.startswith("summary"))
    snapshots, predictions = (int(word) for word in summary.split()[1:5:2])
    assert snapshots > 60 and predictions > 20, summary


def test_the_live_source_carries_the_frame_it_estimated(hand_video):
    from touchanything.devices.hardware.camera_hands import CameraHands
    from touchanything.devices.hardware.opencv_camera import OpenCVCamera, OpenCVCameraConfig
    from touchanything.devices.rig.rig_inputs import RigInput, build_snapshot, camera_fill, camera_hands_fill

    camera = OpenCVCamera(OpenCVCameraConfig(str(hand_video), loop=True))
    hands = CameraHands(CameraPoseConfig(), camera)
    with camera:
        with hands:
            deadline = time.monotonic() + 20  # both hands found, and more than 5 estimates however slow the CPU
            while (reading := hands.latest()) is None or not reading.estimate.valid.all() or hands.counters.samples <= 5:
                assert time.monotonic() < deadline, hands.status()
                time.sleep(0.02)
            time.sleep(0.3)
            status, counters = hands.status(), hands.counters
        reading = hands.latest()  # kept after disconnect; the camera goes on with newer frames
        time.sleep(0.1)
        assert camera.latest().sequence > 0
        inputs = [RigInput("ego", camera, camera_fill("ego")), RigInput("camera hands", hands, camera_hands_fill())]
        snapshot = build_snapshot(inputs, 0, reading.t_us + 1000, 10**9)
    assert "hands" in status and counters.samples > 5, status
    assert snapshot.pose_source == POSE_FROM_CAMERA and snapshot.joints_valid.tolist() == reading.estimate.valid.tolist()
    assert snapshot.images["ego"] is reading.image  # the frame the pose belongs to, not the camera's newest
    assert snapshot.stage_ms == {STAGE: reading.estimate.ms} and snapshot.joints.shape == (42, 3)
    np.testing.assert_array_equal(snapshot.joints, reading.estimate.joints)


def test_the_webcam_scene_file_reads_and_bad_hands_settings_are_one_line(tmp_path):
    from touchanything.app.sessions.scene import read_scene

    scene = read_scene(Path(__file__).resolve().parents[2] / "scenes" / "webcam.toml")
    assert scene.hands == CameraPoseConfig() and scene.cameras["ego"].source == 0
    path = tmp_path / "scene.toml"
    ego = '[cameras.ego]\nkind = "opencv"\nsource = 0\n'
    for text, message in [('[hands]\nsource = "camera"\n', '[hands] source = "camera" estimates the hands from the ego '
                           'camera: add [cameras.ego]'),
                          (ego + '[hands]\nsource = "camera"\nmirror = "yes"\n', "[hands] mirror: expected true or false"),
                          (ego + '[hands]\nsource = "camera"\nsmoothing = 1.5\n', "smoothing must lie in [0, 1)"),
                          (ego + '[hands]\nsource = "camera"\nport = 1\n', "[hands] got an unexpected keyword argument 'port'")]:
        path.write_text(text)
        with pytest.raises(UserError) as error:
            read_scene(path)
        assert message in str(error.value) and "\n" not in str(error.value), str(error.value)


def touchanything(*argv: str) -> subprocess.CompletedProcess:
    """The console script in a fresh process: what a user sees on the terminal, MediaPipe's own logging
    (written by its C++ side straight to the process's stderr) included."""
    return subprocess.run([str(Path(sys.executable).with_name("touchanything")), *argv], capture_output=True, text=True,
                          timeout=300)


def test_pose_on_gloved_hands_says_that_gloves_are_not_detected(tmp_path, capsys):
    sample = next((Path(__file__).resolve().parents[2] / "recordings" / "sample").glob("*/*/*/chest.mp4"))
    reader, writer = VideoReader(sample), VideoWriter(tmp_path / "gloved.mp4", fragmented=False)
    for i in range(0, 150, 15):  # ten frames of the sample's simulated gloved hands, in contact half the time
        writer.write(reader.read(i))
    writer.close()
    reader.close()
    assert main(["pose", str(tmp_path / "gloved.mp4"), "--out", str(tmp_path / "w.json")]) == 0
    out = capsys.readouterr().out
    assert "left hand in 0, right hand in 0 of 10 frames" in out
    assert "no hand   found in any frame: the camera estimate finds bare hands only — gloved hands" in out


def test_the_terminal_shows_no_library_logging_and_one_line_for_a_missing_model(hand_video, tmp_path):
    done = touchanything("pose", str(hand_video), "--out", str(tmp_path / "wilor_hands.json"))
    assert done.returncode == 0, done.stderr
    noise = [line for line in done.stderr.replace("\r", "\n").splitlines() if line and not line.startswith("pose:")]
    assert not noise, noise
    scene = tmp_path / "webcam.toml"
    scene.write_text(f'[cameras.ego]\nkind = "opencv"\nsource = "{hand_video}"\n[hands]\nsource = "camera"\n'
                     'model = "missing.task"\n')
    failed = touchanything("live", "--scene", str(scene), "--headless", "--seconds", "1")
    assert failed.returncode == 2 and failed.stdout == ""
    assert failed.stderr == (f"touchanything live: error: {tmp_path / 'missing.task'}: hand model file not found; build it "
                             "with `make hand-model (or: python scripts/build_hand_model.py)`\n")
