"""What a model is, on screen: the model card beside a checkpoint names the model, its training data and its
held-out accuracy in the model line (dashboard, replay summary) and under the predicted maps of the comparison
video; a prediction from camera-estimated bare hands by a model trained on simulated gloves says it is
illustrative."""
from __future__ import annotations

import math
import shutil

import numpy as np

from touchanything.app.sessions.engine_choice import choose, illustrative_note, model_label, model_name
from touchanything.app.sessions.setting_choice import running_accuracy
from touchanything.inference.model.model_card import CARD_FILE, ModelCard, read_card, write_card
from touchanything.viz.comparison_video import CAMERA_HEIGHT, PANEL_HEIGHT, comparison_frame

SIMULATED = ModelCard("nano", "simulated EgoTouch world, 162 episodes",
                      {"test_seen": {"volumetric_iou": 0.5512, "contact_iou": 0.6}, "test_unseen": {"volumetric_iou": 0.5349}})


def carded_checkpoint(tmp_path, card: ModelCard | None):
    """A copy of a real bundled checkpoint (and its config) in its own folder, with `card` beside it."""
    folder = tmp_path / "model"
    shutil.copytree("models/nano", folder, ignore=shutil.ignore_patterns(CARD_FILE))
    if card is not None:
        write_card(folder, card)
    return folder / "best_model.pth"


def test_a_card_round_trips_and_summarises_the_held_out_accuracy(tmp_path):
    write_card(tmp_path, SIMULATED)
    card = read_card(tmp_path / "best_model.pth")
    assert card == SIMULATED
    assert card.summary() == "nano — trained on simulated data; held-out V-IoU 0.55 seen / 0.53 unseen objects"
    pose = ModelCard("nano_pose_only", "real EgoTouch", {"test_seen": {"volumetric_iou": math.nan}}, pose_only=True)
    assert pose.summary() == "nano_pose_only (pose only) — trained on real EgoTouch"  # a NaN score is not shown


def test_a_missing_or_broken_card_names_the_model_by_its_path(tmp_path):
    checkpoint = carded_checkpoint(tmp_path, None)
    assert read_card(checkpoint) is None and model_name(choose(checkpoint)) == str(checkpoint)
    for text in ("", "{", "[]", '{"name": "x"}', '{"name": "x", "trained_on": "y", "held_out": {"a": {"b": "c"}}}'):
        (checkpoint.parent / CARD_FILE).write_text(text)
        assert read_card(checkpoint) is None, text


def test_the_model_line_names_the_model_and_where_it_was_trained(tmp_path):
    choice = choose(carded_checkpoint(tmp_path, SIMULATED), runtime="onnx", precision="int8")
    assert model_label(choice) == "nano — trained on simulated data (onnx-int8)"  # the accuracy is said once, apart
    assert running_accuracy(choice, ()).line == "model card: held-out V-IoU 0.55 seen / 0.53 unseen objects"


def test_camera_poses_make_a_simulated_model_illustrative(tmp_path):
    simulated = choose(carded_checkpoint(tmp_path, SIMULATED))
    assert illustrative_note(simulated, camera_pose=True).startswith("illustrative only: bare-hand poses from the camera")
    assert illustrative_note(simulated, camera_pose=False) == ""
    write_card(simulated.checkpoint.parent, ModelCard("mine", "real EgoTouch recordings"))
    assert illustrative_note(simulated, camera_pose=True) == ""  # trained on real hands: no warning
    (simulated.checkpoint.parent / CARD_FILE).unlink()
    assert illustrative_note(simulated, camera_pose=True) == ""  # unknown training data: nothing claimed


def test_the_caption_is_drawn_under_the_predicted_maps():
    images = {"ego": np.full((270, 480, 3), 90, np.uint8)}
    grids = np.zeros((2, 21, 21), np.float32)
    plain = comparison_frame(images, grids, grids, "footer")
    captioned = comparison_frame(images, grids, grids, "footer", caption=("nano — trained on simulated data", "illustrative"))
    changed = np.argwhere((plain != captioned).any(axis=2))
    assert plain.shape == captioned.shape and len(changed)
    rows = changed[:, 0]
    assert CAMERA_HEIGHT + PANEL_HEIGHT - 50 <= rows.min() and rows.max() < CAMERA_HEIGHT + PANEL_HEIGHT
    amber = captioned[CAMERA_HEIGHT + PANEL_HEIGHT - 20:CAMERA_HEIGHT + PANEL_HEIGHT]
    assert ((amber[..., 0] > 200) & (amber[..., 2] < 100)).any()  # the warning line is amber (the frame is RGB)
