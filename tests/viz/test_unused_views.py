"""A view the model takes nothing from is marked the one way everywhere — "left wrist camera — not used" — in the
dashboard's camera panels and the comparison video (dimmed to 35 % too) and in the Rerun recording (a labelled
point on that camera, from the frame it is not used until it is used again): the views outside the chosen view
set, and every view of a pose-only model (trained on black frames). (The eval video: tests/inference/test_eval.py;
the eval recording: tests/timing/test_rerun.py; a session's views after a switch: tests/app/test_figures_restart.py.)"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from rerun.chunk import RrdReader

from helpers.rerun_reading import recording_rows
from touchanything.app.cli import main
from touchanything.app.sessions.bundled import MODELS_DIR
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.view_sets import view_label, views_used
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.viz.comparison_video import CAMERA_HEIGHT, comparison_frame
from touchanything.viz.dashboard.dashboard_panels import camera_panel
from touchanything.viz.frame_facts import frame_facts
from touchanything.viz.pressure_panel import BACKGROUND, put_text
from touchanything.viz.rerun_recording import RerunRecording, RerunTarget

LABELS = {"ego": "head camera — not used", "wrist_left": "left wrist camera — not used",
          "wrist_right": "right wrist camera — not used"}
"""What each view is called when the model does not use it, written out."""


def dim(image: np.ndarray) -> np.ndarray:
    return (image * 0.35).astype(np.uint8)


def test_which_views_a_model_uses_and_what_an_unused_one_is_called():
    assert views_used(VIEW_NAMES, pose_only=False) == ("ego", "wrist_left", "wrist_right")
    assert views_used(("wrist_right", "ego"), pose_only=False) == ("ego", "wrist_right")
    assert views_used(VIEW_NAMES, pose_only=True) == ()  # black frames: nothing of any view
    assert views_used(("wrist_left", "wrist_right"), pose_only=False) == ()  # no head camera, no prediction
    assert {view: view_label(view, used=False) for view in VIEW_NAMES} == LABELS
    assert view_label("wrist_left") == "left wrist camera"


def test_the_comparison_video_dims_and_labels_the_views_the_model_does_not_use():
    rng = np.random.default_rng(1)
    images = {v: rng.integers(0, 255, (270, 480, 3), np.uint8) for v in VIEW_NAMES}
    frame = comparison_frame(images, None, None, "footer", used=("ego",))
    for k, (view, text) in enumerate((("ego", "head camera"), ("wrist_left", LABELS["wrist_left"]),
                                      ("wrist_right", LABELS["wrist_right"]))):
        tile = cv2.resize(images[view], (480, CAMERA_HEIGHT), interpolation=cv2.INTER_AREA)
        tile = tile if view == "ego" else dim(tile)
        put_text(tile, text, (8, 22), 0.6)
        assert np.array_equal(frame[:CAMERA_HEIGHT, 480 * k:480 * (k + 1)], tile), view
    # a view not read at all (replay --views ego reads the head camera only) says "not used", not "no image"
    frame = comparison_frame({"ego": images["ego"]}, None, None, "footer", used=("ego",))
    tile = np.empty((CAMERA_HEIGHT, 480, 3), np.uint8)
    tile[:] = BACKGROUND
    put_text(tile, LABELS["wrist_left"], (8, 22), 0.6)
    assert np.array_equal(frame[:CAMERA_HEIGHT, 480:960], tile)


def test_the_dashboard_camera_panel_dims_and_labels_an_unused_view():
    image = np.random.default_rng(2).integers(0, 255, (48, 64, 3), np.uint8)
    snapshot = Snapshot(frame_index=0, t_us=0, images={"wrist_left": image}, joints=np.zeros((42, 3), np.float32),
                        joints_valid=np.zeros(2, bool))
    for used, text in ((True, "left wrist camera"), (False, LABELS["wrist_left"])):
        expected = cv2.resize(image, (192, 144), interpolation=cv2.INTER_LINEAR)
        expected = expected if used else dim(expected)
        put_text(expected, text, (6, 16), 0.4)
        assert np.array_equal(camera_panel(snapshot, "wrist_left", used, 192, 144, None), expected), used


def static_labels(path: Path, store=None) -> dict[str, list]:
    """{entity: its static Points2D labels} of the "not used" marks in a recording."""
    labels = {}
    for chunk in RrdReader(path).stream(store=store):
        batch = chunk.to_record_batch()
        if chunk.is_static and chunk.entity_path.endswith("/not_used") and "Points2D:labels" in batch.schema.names:
            labels[chunk.entity_path] = batch.column("Points2D:labels").to_pylist()[0]
    return labels


def marked_frames(rows: dict, view: str) -> list[int]:
    """The frames at which `view` is marked "not used" (a row placing the mark; a clear takes it away)."""
    entity = rows.get(f"/cameras/{view}/not_used")
    return [] if entity is None else entity.data_frames("Points2D:positions")


def test_rerun_marks_a_view_from_the_frame_it_is_not_used_until_it_is_used_again(tmp_path):
    path = tmp_path / "views.rrd"
    recording = RerunRecording(RerunTarget(path), "views", {})
    image = np.zeros((48, 64, 3), np.uint8)
    nothing = frame_facts(None, None, None, TactileLayout.default().bend)
    used = [VIEW_NAMES, VIEW_NAMES, ("ego",), ("ego",), VIEW_NAMES, (), ()]  # the dashboard's views, then pose-only
    for frame, views in enumerate(used):
        recording.log_observation(frame, frame / 30, {v: image for v in VIEW_NAMES}, np.zeros((42, 3), np.float32),
                                  np.zeros(2, bool), None, nothing, {}, views)
    recording.close()
    rows, _ = recording_rows(path)
    assert {view: marked_frames(rows, view) for view in VIEW_NAMES} == {"ego": [5], "wrist_left": [2, 5], "wrist_right": [2, 5]}
    cleared = rows["/cameras/wrist_left/not_used"]
    assert [f for f, v in zip(cleared.frames, cleared.values["Points2D:positions"]) if not v] == [4]  # used again at 4
    assert static_labels(path) == {f"/cameras/{view}/not_used": [text] for view, text in LABELS.items()}


def test_replay_marks_the_views_outside_its_view_set_and_every_view_of_a_pose_only_model(episode_dir, tmp_path, capsys):
    video, rrd = tmp_path / "ego.mp4", tmp_path / "ego.rrd"
    assert main(["replay", str(episode_dir), "--views", "ego", "--out", str(video), "--rerun", str(rrd)]) == 0
    rows, _ = recording_rows(rrd)
    assert {view: marked_frames(rows, view) for view in VIEW_NAMES} == {"ego": [], "wrist_left": [0], "wrist_right": [0]}
    with VideoReader(video) as reader:
        frame = reader.read(20)
    background = np.array(BACKGROUND, np.float64)
    for k in (1, 2):  # the wrist cameras are not read: background under their "not used" label
        assert np.abs(frame[60:CAMERA_HEIGHT, 480 * k:480 * (k + 1)] - background).mean() < 4, k
    assert np.abs(frame[60:CAMERA_HEIGHT, :480] - background).mean() > 20  # the head camera is shown

    pose_only = tmp_path / "pose_only.rrd"
    checkpoint = MODELS_DIR / "nano_pose_only" / "best_model.pth"
    assert main(["replay", str(episode_dir), "--checkpoint", str(checkpoint), "--rerun", str(pose_only)]) == 0
    rows, _ = recording_rows(pose_only)
    assert {view: marked_frames(rows, view) for view in VIEW_NAMES} == dict.fromkeys(VIEW_NAMES, [0])
    capsys.readouterr()
