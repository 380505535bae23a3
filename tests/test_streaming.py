"""StreamingEngine: exactness against the batch forward, gaps, view changes, seek, knobs and invalid hands."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import find_hdf5_files, open_episode
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.frame_ring import CachedFrame, FrameRing
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.trajectory_prediction import predict_trajectory
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import to_model_input
from touchanything.inference.model.touch_model import TouchAnything

TOLERANCE = 1e-4
LAYOUT = TactileLayout.default()


@pytest.fixture(scope="module")
def model() -> TouchAnything:
    """nano with two temporal layers, so the head runs a full layer before the output-only last one."""
    torch.manual_seed(3)
    nano = preset("nano")
    deeper = dataclasses.replace(nano.temporal_transformer, num_layers=2)
    return TouchAnything(dataclasses.replace(nano, temporal_transformer=deeper)).eval()


def random_stream(size: int, frames: int, seed: int = 0, valid: np.ndarray | None = None) -> dict:
    rng = np.random.default_rng(seed)
    return {"images": {v: rng.integers(0, 256, (frames, size, size, 3), dtype=np.uint8) for v in VIEW_NAMES},
            "joints": (rng.normal(0, 2, (frames, 42, 3)) + [0, 0, 40]).astype(np.float32),
            "valid": np.ones((frames, 2), bool) if valid is None else valid}


def snapshot(stream: dict, i: int, views=VIEW_NAMES) -> Snapshot:
    return Snapshot(i, i * 33_333, {v: stream["images"][v][i] for v in views}, stream["joints"][i], stream["valid"][i])


def batch_output(model: TouchAnything, stream: dict, frames: np.ndarray, views) -> np.ndarray:
    """The batch forward of the clip made of `frames` → (8, 2, 21, 21)."""
    inputs = {v: to_model_input(stream["images"][v][frames])[None] for v in views}
    poses = torch.from_numpy(prepare_poses(stream["joints"][frames], stream["valid"][frames]))[None]
    with torch.no_grad():
        return model(poses=poses, views=inputs)["tactile"][0].numpy()


def clip(end: int) -> np.ndarray:
    return np.arange(end - 14, end + 1, 2)


def run(engine: StreamingEngine, stream: dict, indices, views=VIEW_NAMES) -> dict[int, object]:
    return {p.frame_index: p for i in indices for p in engine.step(snapshot(stream, i, views))}


def close(prediction, expected: np.ndarray) -> bool:
    return float(np.nanmax(np.abs(prediction.pressure - (expected + LAYOUT.nan_mask())))) < TOLERANCE


@pytest.mark.parametrize("views", [("ego",), ("ego", "wrist_left"), ("ego", "wrist_right"), VIEW_NAMES])
def test_newest_frame_equals_the_batch_forward(model, views):
    stream = random_stream(model.config.image_size, 22, seed=len(views))
    engine = StreamingEngine(model, EngineSetting(views=views))
    predictions = run(engine, stream, range(22), views)
    assert sorted(predictions) == list(range(22))
    for end in range(14, 22):
        assert close(predictions[end], batch_output(model, stream, clip(end), views)[-1])
        assert predictions[end].window_exact and predictions[end].views_used == views
    assert not predictions[3].window_exact  # start padding


def test_centre_output_equals_the_batch_forward_at_position_four(model):
    stream = random_stream(model.config.image_size, 26, seed=7)
    engine = StreamingEngine(model, EngineSetting(output="centre"))
    predictions = run(engine, stream, range(26))
    predictions.update({p.frame_index: p for p in engine.drain()})
    assert sorted(predictions) == list(range(26))
    for frame in range(8, 20):
        assert close(predictions[frame], batch_output(model, stream, clip(frame + 6), VIEW_NAMES)[4])


def test_stitched_output_equals_the_official_offline_protocol(sim_hdf5_root):
    torch.manual_seed(0)
    model = TouchAnything(preset("nano")).eval()
    path = find_hdf5_files(sim_hdf5_root)[0]
    with open_episode(path) as episode:
        expected = predict_trajectory(model, episode, VIEW_NAMES, batch_size=8, ego_path="views").stitched
        from touchanything.devices.rig.replay import ReplayConfig, ReplaySource

        engine = StreamingEngine(model, EngineSetting(output="stitched", invalid_hands="official"))
        predictions = [p for s in ReplaySource(episode, ReplayConfig(speed=None)) for p in engine.step(s)]
        predictions += engine.drain()
    assert [p.frame_index for p in predictions] == list(range(episode.num_frames))
    got = np.stack([p.pressure for p in predictions])
    assert float(np.nanmax(np.abs(got - (expected + LAYOUT.nan_mask())))) < TOLERANCE


def test_dropped_frames_use_the_nearest_cached_frames():
    ring = FrameRing()
    for i in [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 15, 17, 19, 20]:
        ring.add(CachedFrame(i, None, np.zeros((42, 3)), np.ones(2, bool), ("ego",), i))
    window = ring.window()
    assert [f.frame_index for f in window.frames] == [6, 8, 10, 12, 13, 15, 17, 20]  # 14 → 13 (tie: earlier)
    assert not window.exact and not window.padded
    ring.add(CachedFrame(40, None, np.zeros((42, 3)), np.ones(2, bool), ("ego",), 40))
    assert [f.frame_index for f in ring.window().frames] == [40] * 8 and len(ring) == 1


def test_views_may_change_mid_stream(model):
    size = model.config.image_size
    stream = random_stream(size, 46, seed=11)
    engine = StreamingEngine(model, EngineSetting())
    before = run(engine, stream, range(30))
    after = run(engine, stream, range(30, 46), ("ego",))
    assert before[29].views_used == VIEW_NAMES and after[30].views_used == ("ego",)
    assert close(after[44], batch_output(model, stream, clip(44), ("ego",))[-1])
    engine.set_views(("ego", "wrist_right"))
    again = run(StreamingEngine(model, EngineSetting(views=("ego", "wrist_right"))), stream, range(46))
    assert again[45].views_used == ("ego", "wrist_right")
    assert close(again[45], batch_output(model, stream, clip(45), ("ego", "wrist_right"))[-1])


def test_seek_clears_the_cache(model):
    stream = random_stream(model.config.image_size, 40, seed=5)
    engine = StreamingEngine(model, EngineSetting())
    run(engine, stream, range(30))
    seeked = run(engine, stream, range(10, 25))
    fresh = run(StreamingEngine(model, EngineSetting()), stream, range(10, 25))
    for frame in range(10, 25):
        assert np.array_equal(seeked[frame].pressure, fresh[frame].pressure, equal_nan=True)
    assert close(seeked[24], batch_output(model, stream, clip(24), VIEW_NAMES)[-1])


def test_invalid_hands_are_skipped_or_fed_as_official_minus_ten(model):
    valid = np.ones((20, 2), bool)
    valid[:, 1] = False
    valid[19] = False
    stream = random_stream(model.config.image_size, 20, seed=2, valid=valid)
    skip = run(StreamingEngine(model, EngineSetting()), stream, range(20))
    official = run(StreamingEngine(model, EngineSetting(invalid_hands="official")), stream, range(20))
    assert skip[16].hands_predicted == (True, False) and skip[16].status == "right hand: no pose"
    assert np.nanmax(skip[16].pressure[1]) == 0.0
    assert official[16].hands_predicted == (True, True)
    assert close(official[16], batch_output(model, stream, clip(16), VIEW_NAMES)[-1])
    assert skip[19].hands_predicted == (False, False) and "head" not in skip[19].timings_ms
    assert "encode" in skip[19].timings_ms and skip[19].status == "no valid hand pose"


def test_no_ego_view_gives_no_prediction_with_the_reason(model):
    stream = random_stream(model.config.image_size, 3)
    engine = StreamingEngine(model, EngineSetting())
    (prediction,) = engine.step(snapshot(stream, 0, ("wrist_left", "wrist_right")))
    assert prediction.pressure is None and "no ego" in prediction.status
    assert "encode" not in prediction.timings_ms


def test_every_kth_frame_holds_the_last_prediction(model):
    stream = random_stream(model.config.image_size, 12)
    predictions = run(StreamingEngine(model, EngineSetting(every=3)), stream, range(12))
    computed = [i for i, p in predictions.items() if not p.held]
    assert computed == [0, 3, 6, 9]
    assert predictions[4].pressure is predictions[3].pressure and predictions[4].held
