"""StreamingEngine: exactness against the batch forward, gaps, view changes, seek, knobs and invalid hands; and its
bookkeeping by value: latency from the injected clock, stage timings in milliseconds, when a window counts as exact,
what `drain()` returns per output position, `reset()` and a seek (the every-k-th count restarts), the status line
per hand, the joint ids the head gets, a frame without an ego view, a pose-only model, a centre frame repeated by a
drop, and stitching around a frame without hands."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import find_hdf5_files, open_episode
from touchanything.inference.engine import streaming_engine
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


# --- the engine's bookkeeping, by value ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def nano_model() -> TouchAnything:
    torch.manual_seed(3)
    return TouchAnything(preset("nano")).eval()


def stream(nano_model: TouchAnything, frames: int, seed: int = 0, valid: np.ndarray | None = None) -> list[Snapshot]:
    rng = np.random.default_rng(seed)
    size = nano_model.config.image_size
    images = {v: rng.integers(0, 256, (frames, size, size, 3), dtype=np.uint8) for v in VIEW_NAMES}
    joints = (rng.normal(0, 2, (frames, 42, 3)) + [0, 0, 40]).astype(np.float32)
    valid = np.ones((frames, 2), bool) if valid is None else valid
    return [Snapshot(i, i * 33_333, {v: images[v][i] for v in VIEW_NAMES}, joints[i], valid[i]) for i in range(frames)]


def predictions_by_frame(engine: StreamingEngine, snapshots) -> dict:
    return {p.frame_index: p for s in snapshots for p in engine.step(s)}


def test_latency_is_the_injected_clock_minus_the_capture_time(nano_model):
    snapshots = stream(nano_model, 4)
    engine = StreamingEngine(nano_model, EngineSetting(every=2), clock=lambda: 5.0)  # 5 s = 5 000 000 µs
    got = predictions_by_frame(engine, snapshots)
    assert [got[i].latency_ms for i in range(4)] == [(5_000_000 - i * 33_333) / 1000 for i in range(4)]
    assert got[1].held and got[1].latency_ms == pytest.approx(4966.667)
    (none,) = engine.step(dataclasses.replace(snapshots[3], frame_index=7, images={}))
    assert none.pressure is None and none.latency_ms == pytest.approx((5_000_000 - 3 * 33_333) / 1000)


def test_stage_timings_are_milliseconds(nano_model):
    got = predictions_by_frame(StreamingEngine(nano_model, EngineSetting()), stream(nano_model, 2))
    timings = got[1].timings_ms
    assert set(timings) == {"preprocess", "encode", "head", "total"}
    assert all(0.0 < value < 60_000 for value in timings.values())
    assert timings["encode"] > 0.01 and timings["head"] > 0.01  # a forward pass takes more than 10 µs
    assert timings["total"] >= timings["preprocess"] + timings["encode"] + timings["head"]


def test_a_window_is_exact_once_every_ideal_frame_is_cached_and_none_lies_before_the_start(nano_model):
    snapshots = stream(nano_model, 24)
    got = predictions_by_frame(StreamingEngine(nano_model, EngineSetting()), [s for s in snapshots if s.frame_index != 20])
    assert [i for i, p in sorted(got.items()) if p.window_exact] == [14, 15, 16, 17, 18, 19, 21, 23]
    assert got[13].status == "ok" and got[14].hands_predicted == (True, True)


def test_drain_returns_what_each_output_position_holds_back(nano_model):
    snapshots = stream(nano_model, 20, seed=4)
    assert StreamingEngine(nano_model, EngineSetting()).drain() == []
    newest = StreamingEngine(nano_model, EngineSetting())
    predictions_by_frame(newest, snapshots)
    assert newest.drain() == []
    centre = StreamingEngine(nano_model, EngineSetting(output="centre"))
    emitted = predictions_by_frame(centre, snapshots)
    assert sorted(emitted) == list(range(14))  # the window ending on 19 has frame 13 at position 4
    drained = centre.drain()
    assert [p.frame_index for p in drained] == list(range(14, 20))
    # Each with the newest-frame output of the window ending on it, from the 15 frames still cached (5–19): only
    # the window ending on 19 has all its ideal frames.
    assert [p.window_exact for p in drained] == [False] * 5 + [True]
    reference = predictions_by_frame(StreamingEngine(nano_model, EngineSetting()), snapshots)
    assert np.allclose(drained[-1].pressure, reference[19].pressure, atol=1e-6, equal_nan=True)
    assert centre.drain() == []  # nothing is held twice
    stitched = StreamingEngine(nano_model, EngineSetting(output="stitched"))
    emitted = predictions_by_frame(stitched, snapshots)
    assert sorted(emitted) == list(range(6))  # the first window not padded ends on 14; frame 5 is done at 19
    assert [p.frame_index for p in stitched.drain()] == list(range(6, 20))
    assert stitched.drain() == []


def test_reset_forgets_the_cache_and_what_was_emitted(nano_model):
    snapshots = stream(nano_model, 18, seed=6)
    engine = StreamingEngine(nano_model, EngineSetting(output="centre"))
    predictions_by_frame(engine, snapshots)
    engine.reset()
    again = predictions_by_frame(engine, snapshots[:12])
    fresh = predictions_by_frame(StreamingEngine(nano_model, EngineSetting(output="centre")), snapshots[:12])
    assert sorted(again) == sorted(fresh) == list(range(6))
    assert all(np.array_equal(again[i].pressure, fresh[i].pressure, equal_nan=True) for i in fresh)


def test_the_status_names_the_hand_without_a_pose(nano_model):
    valid = np.array([[True, True], [False, True], [True, False], [False, False]])
    got = predictions_by_frame(StreamingEngine(nano_model, EngineSetting()), stream(nano_model, 4, valid=valid))
    assert [got[i].status for i in range(4)] == ["ok", "left hand: no pose", "right hand: no pose", "no valid hand pose"]
    assert [got[i].hands_predicted for i in range(4)] == [(True, True), (False, True), (True, False), (False, False)]


def test_after_a_seek_every_kth_frame_counts_from_the_new_start(nano_model):
    snapshots = stream(nano_model, 8, seed=7)
    engine = StreamingEngine(nano_model, EngineSetting(every=3))
    first = predictions_by_frame(engine, snapshots[:5])
    again = predictions_by_frame(engine, snapshots)  # frame 0 again: a seek
    assert [i for i, p in first.items() if not p.held] == [0, 3]
    assert [i for i, p in again.items() if not p.held] == [0, 3, 6]


def test_timings_are_the_perf_counter_differences_times_a_thousand(nano_model, monkeypatch):
    ticks = iter(np.arange(0.0, 1000.0, 0.5))
    monkeypatch.setattr(streaming_engine.time, "perf_counter", lambda: float(next(ticks)))
    (prediction,) = StreamingEngine(nano_model, EngineSetting()).step(stream(nano_model, 1)[0])
    timings = prediction.timings_ms
    assert set(timings) == {"preprocess", "encode", "head", "total"}
    assert all(value > 0 and value % 500.0 == 0 for value in timings.values()), timings  # steps of 0.5 s


def test_the_head_gets_the_official_joint_ids_of_the_hands_it_predicts(nano_model):
    valid = np.array([[True, True], [False, True], [True, False]])
    engine = StreamingEngine(nano_model, EngineSetting())
    calls = []
    head = engine.runtime.head

    def recording(tokens, joints, joint_ids, positions):
        calls.append(joint_ids.tolist())
        return head(tokens, joints, joint_ids, positions)

    engine.runtime.head = recording
    predictions_by_frame(engine, stream(nano_model, 3, valid=valid))
    assert calls == [list(range(42)), list(range(21, 42)), list(range(21))]  # 0–20 left, 21–41 right


def test_a_frame_without_an_ego_view_says_so_in_every_field(nano_model):
    snapshot = stream(nano_model, 1)[0]
    (prediction,) = StreamingEngine(nano_model, EngineSetting()).step(dataclasses.replace(snapshot, images={}))
    assert (prediction.pressure, prediction.hands_predicted, prediction.window_exact, prediction.views_used) == (
        None, (False, False), False, ())


def test_a_pose_only_model_sees_black_frames_whatever_the_cameras_show(nano_model):
    blank = TouchAnything(dataclasses.replace(nano_model.config, blank_images=True)).eval()
    blank.load_state_dict(nano_model.state_dict())
    snapshots = stream(nano_model, 3, seed=8)
    black = [dataclasses.replace(s, images={v: np.zeros_like(i) for v, i in s.images.items()}) for s in snapshots]
    got = predictions_by_frame(StreamingEngine(blank, EngineSetting()), snapshots)
    want = predictions_by_frame(StreamingEngine(nano_model, EngineSetting()), black)
    assert all(np.allclose(got[i].pressure, want[i].pressure, atol=1e-6, equal_nan=True) for i in range(3))


def test_the_centre_output_emits_each_frame_once_when_a_drop_repeats_the_centre_frame(nano_model):
    snapshots = [s for s in stream(nano_model, 24, seed=9) if s.frame_index != 15]
    engine = StreamingEngine(nano_model, EngineSetting(output="centre"))
    emitted = [p.frame_index for s in snapshots for p in engine.step(s)] + [p.frame_index for p in engine.drain()]
    assert emitted == sorted(set(emitted))  # at 21 the centre is 14 again (15 missing, 14 and 16 tie): not re-emitted
    assert 15 not in emitted and emitted[:3] == [0, 1, 2]


def test_stitching_a_frame_without_hands_leaves_the_other_frames_as_they_were(nano_model):
    valid = np.ones((26, 2), bool)
    valid[10] = False  # frame 10: no hand; it shares 7 windows with frame 12
    valid[:, 1] = False  # the right hand never has a pose
    snapshots = stream(nano_model, 26, seed=10, valid=valid)
    every = stream(nano_model, 26, seed=10, valid=np.column_stack([np.ones(26, bool), np.zeros(26, bool)]))
    got, want = (predictions_by_frame(StreamingEngine(nano_model, EngineSetting(output="stitched")), s) for s in (snapshots, every))
    assert sorted(got) == sorted(want) == list(range(12))
    assert got[10].hands_predicted == (False, False) and got[0].hands_predicted == (True, False)  # 0: in one window only
    assert all(np.allclose(got[i].pressure, want[i].pressure, atol=1e-6, equal_nan=True) for i in range(12) if i != 10)
