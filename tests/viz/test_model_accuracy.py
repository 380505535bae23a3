"""One held-out accuracy per model: the atlas's row of the running setting, else its reference
setting's row (said as such), else the model card's; the session's model line carries that one number, the same
the atlas line ends with, never the card's beside the atlas's."""
from __future__ import annotations

import json
from pathlib import Path

from helpers.atlas_file import write_atlas
from tests.timing.test_dashboard import NANO
from touchanything.app.sessions.bundled import MODELS_DIR
from touchanything.app.sessions.engine_choice import build_engine
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.evaluation.atlas import read_atlas
from touchanything.inference.model.model_card import ModelCard, read_card
from touchanything.viz.model_accuracy import ModelAccuracy, model_accuracy

CARD = ModelCard("nano", "simulated EgoTouch world", {"test_seen": {"volumetric_iou": 0.654},
                                                      "test_unseen": {"volumetric_iou": 0.546}})


def test_the_running_settings_atlas_row_comes_first(tmp_path):
    rows = read_atlas(write_atlas(tmp_path / "engine.json"))
    accuracy = model_accuracy(EngineSetting("nano"), rows, CARD)
    assert accuracy == ModelAccuracy("held-out V-IoU 0.600 [0.580, 0.620] on 108 held-out trajectories (atlas)",
                                     "V-IoU 0.600 in the atlas")


def test_a_setting_the_atlas_lacks_gives_its_reference_rows_accuracy_and_says_so(tmp_path):
    rows = read_atlas(write_atlas(tmp_path / "engine.json"))
    accuracy = model_accuracy(EngineSetting("nano", every=3), rows, CARD)
    assert accuracy.line == ("held-out V-IoU 0.600 [0.580, 0.620] on 108 held-out trajectories (atlas, reference "
                             "setting nano/torch-fp32/all: nano/torch-fp32/all/every3 is not in the atlas)")
    assert accuracy.caption == "not in the atlas; reference nano/torch-fp32/all V-IoU 0.600"


def test_without_atlas_rows_the_card_gives_it_and_is_named():
    accuracy = model_accuracy(EngineSetting("nano"), (), CARD)
    assert accuracy == ModelAccuracy("model card: held-out V-IoU 0.65 seen / 0.55 unseen objects",
                                     "not in the atlas (model card: V-IoU 0.65 seen / 0.55 unseen)")
    assert model_accuracy(EngineSetting("nano"), (), None) == ModelAccuracy()


def test_a_card_with_its_trajectory_counts_says_them(tmp_path):
    (tmp_path / "model_card.json").write_text(json.dumps({
        "name": "mine", "trained_on": "simulated EgoTouch world",
        "held_out": {"test_seen": {"volumetric_iou": 0.6, "trajectories": 54},
                     "test_unseen": {"volumetric_iou": 0.5, "trajectories": 50}}}))
    card = read_card(tmp_path / "best_model.pth")
    assert model_accuracy(EngineSetting("mine"), (), card).line == \
        "model card: held-out V-IoU 0.60 seen / 0.50 unseen objects on 104 held-out trajectories"


def _state_lines(episode_dir: Path, atlas: Path) -> tuple[str, str]:
    with open_episode(episode_dir) as episode:
        session = ReplaySession(episode, build_engine(NANO), NANO)
        session.use_atlas(atlas)
        state = session.start().state()
        session.close()
    return state.model, state.accuracy.caption


def test_the_model_line_shows_the_atlas_accuracy_only(episode_dir, tmp_path):
    """nano's card says 0.xx seen / 0.yy unseen, the atlas 0.600: the model line says the atlas's, as the atlas
    line does, and not the card's."""
    model, caption = _state_lines(episode_dir, write_atlas(tmp_path / "engine.json"))
    card = read_card(MODELS_DIR / "nano" / "best_model.pth")
    assert model.startswith("nano — trained on simulated data (torch-fp32 on cpu); held-out V-IoU 0.600 "), model
    assert caption == "V-IoU 0.600 in the atlas"
    for values in card.held_out.values():
        assert f"{values['volumetric_iou']:.2f}" not in model, model
