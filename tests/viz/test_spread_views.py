"""An ensemble's spread where the prediction is shown: the Rerun recording (its maps, values and view) and the
comparison video (a panel beside the predicted maps); a single model's prediction shows neither."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from rerun.blueprint import Container
from rerun.chunk import RrdReader

from helpers.rerun_reading import recording_rows
from touchanything.app.sessions.bundled import MODELS_DIR
from touchanything.app.sessions.replay_export import ReplaySummary, replay_frames
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.ensemble_engine import load_ensemble
from touchanything.viz.comparison_video import CAMERA_HEIGHT, PANEL_HEIGHT, comparison_frame
from touchanything.viz.frame_facts import frame_facts
from touchanything.viz.pressure_panel import MAP_TITLES, SPREAD_HIGH, SPREAD_TITLE, pressure_panel, unposed_as_nan
from touchanything.viz.replay_frame import ReplayFrameRenderer
from touchanything.viz.rerun_blueprint import default_blueprint
from touchanything.viz.rerun_recording import RerunRecording, RerunTarget

PANELS = slice(CAMERA_HEIGHT, CAMERA_HEIGHT + PANEL_HEIGHT)


def maps() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """measured, predicted and spread (2, 21, 21) on the default layout (NaN outside it)."""
    mask = TactileLayout.default().nan_mask()
    rng = np.random.default_rng(4)
    measured, predicted = (rng.uniform(0, 1, (2, 21, 21)).astype(np.float32) + mask for _ in range(2))
    return measured, predicted, rng.uniform(0, SPREAD_HIGH, (2, 21, 21)).astype(np.float32) + mask


def names(container) -> list[str]:
    out = []
    for item in container.contents:
        out += names(item) if isinstance(item, Container) else [item.name]
    return out


def test_the_blueprint_adds_the_spread_under_the_predicted_map():
    assert names(default_blueprint(spread=True).root_container)[3:7] == [
        f"{title} (left | right)" for title in (MAP_TITLES["measured"], MAP_TITLES["predicted"], SPREAD_TITLE, MAP_TITLES["error"])]
    assert SPREAD_TITLE not in " ".join(names(default_blueprint().root_container))


def record(path: Path, spread: np.ndarray | None, joints: np.ndarray) -> None:
    """Frame 0 both hands, frame 1 the right hand not predicted, frame 2 no prediction."""
    measured, predicted, _ = maps()
    valid = np.array([True, True])
    bend = TactileLayout.default().bend
    recording = RerunRecording(RerunTarget(path), "spread", {})
    for frame, hands in ((0, (True, True)), (1, (True, False))):
        facts = frame_facts(predicted, hands, measured, bend)
        recording.log_prediction(frame, frame / 30, predicted, facts, joints, valid, measured, None, None, spread)
    recording.log_prediction(2, 2 / 30, None, frame_facts(None, None, measured, bend), joints, valid, measured, None, None)
    recording.close()


def blueprint_text(path: Path) -> str:
    """Every component value of the recording's blueprints, as text."""
    reader = RrdReader(path)
    batches = [chunk.to_record_batch() for store in reader.blueprints() for chunk in reader.stream(store=store)]
    return " ".join(str(batch.column(name).to_pylist()) for batch in batches for name in batch.schema.names if ":" in name)


def test_rerun_logs_the_spread_beside_the_prediction(tmp_path):
    joints = np.zeros((42, 3), np.float32)
    joints[:, 2] = 0.5
    _, _, spread = maps()
    record(tmp_path / "e.rrd", spread, joints)
    rows, static = recording_rows(tmp_path / "e.rrd")
    for h, hand in enumerate(("left", "right")):
        values = rows[f"/pressure/spread/{hand}"]
        logged = np.frombuffer(bytes(values.at("DepthImage:buffer", 0)[0]), np.float16).reshape(21, 21)
        np.testing.assert_allclose(logged, spread[h], atol=2e-4, equal_nan=True)
        assert values.data_frames("DepthImage:buffer") == [0, 1]  # no prediction at frame 2: cleared
    unposed = np.frombuffer(bytes(rows["/pressure/spread/right"].at("DepthImage:buffer", 1)[0]), np.float16)
    assert np.isnan(unposed).all()  # the hand not predicted: no spread shown
    assert rows["/pressure/spread"].data_frames("EncodedImage:blob") == [0, 1]
    assert "DepthImage:depth_range" in static["/pressure/spread/left"]
    assert SPREAD_TITLE in blueprint_text(tmp_path / "e.rrd")
    record(tmp_path / "single.rrd", None, joints)
    rows, static = recording_rows(tmp_path / "single.rrd")
    assert not any(entity.startswith("/pressure/spread") for entity in (*rows, *static))
    assert SPREAD_TITLE not in blueprint_text(tmp_path / "single.rrd")


def test_the_comparison_frame_puts_the_spread_beside_the_predicted_maps():
    measured, predicted, spread = maps()
    single = comparison_frame({}, measured, predicted, "footer")
    ensemble = comparison_frame({}, measured, predicted, "footer", spread=spread)
    assert single.shape == ensemble.shape
    bend = TactileLayout.default().bend  # bend cells drawn as such on the pressure panels, not on the spread
    expected = [pressure_panel(measured, MAP_TITLES["measured"], 360, PANEL_HEIGHT, empty="no glove", bend=bend),
                pressure_panel(predicted, MAP_TITLES["predicted"], 360, PANEL_HEIGHT, empty="no pose", bend=bend),
                pressure_panel(spread, SPREAD_TITLE, 360, PANEL_HEIGHT, empty="no pose", high=SPREAD_HIGH),
                pressure_panel(predicted - measured, MAP_TITLES["error"], 360, PANEL_HEIGHT, error=True, bend=bend)]
    np.testing.assert_array_equal(ensemble[PANELS], np.concatenate(expected, axis=1))
    np.testing.assert_array_equal(single[PANELS, :480], pressure_panel(measured, MAP_TITLES["measured"], 480, PANEL_HEIGHT,
                                                                       empty="no glove", bend=bend))


def test_a_replayed_ensemble_shows_its_spread_in_the_video_and_the_recording(episode_dir, tmp_path):
    checkpoint = tmp_path / "pico" / "best_model.pth"
    shutil.copytree(MODELS_DIR / "pico", checkpoint.parent)
    shutil.copytree(MODELS_DIR / "pico", checkpoint.parent / "members" / "2")
    (checkpoint.parent / "ensemble.json").write_text('{"members": ["members/2/best_model.pth"]}')
    engine = load_ensemble(checkpoint, EngineSetting("pico", members=2))
    with open_episode(episode_dir) as episode:
        source = ReplaySource(episode, ReplayConfig(speed=None))
        predictions = {p.frame_index: p for s in ReplaySource(episode, ReplayConfig(speed=None)) for p in engine.step(s)}
        recording = RerunRecording(RerunTarget(tmp_path / "r.rrd"), "replay", {})
        renderer = ReplayFrameRenderer(episode.num_frames)
        frames = list(replay_frames(source, engine, ReplaySummary(video=True), renderer=renderer, rerun=recording))
        recording.close()
    shown = [i for i, p in predictions.items() if p.pressure is not None and any(p.hands_predicted)]
    assert len(shown) > 10 and all(np.nanmax(predictions[i].spread) == 0.0 for i in shown)  # identical members
    for i in shown[:3]:
        p = predictions[i]
        panel = pressure_panel(unposed_as_nan(p.spread, p.hands_predicted), SPREAD_TITLE, 360, PANEL_HEIGHT,
                               empty="no pose", high=SPREAD_HIGH)
        np.testing.assert_array_equal(frames[i][PANELS, 720:1080], panel)
    rows, _ = recording_rows(tmp_path / "r.rrd")
    assert rows["/pressure/spread/left"].data_frames("DepthImage:buffer") == [
        i for i, p in sorted(predictions.items()) if p.pressure is not None]
