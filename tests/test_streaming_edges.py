"""The streaming engine's bookkeeping by value (found by mutation testing, docs/testing.md): latency from the
injected clock, stage timings in milliseconds, when a window counts as exact, what `drain()` returns per output
position, `reset()` and a seek (the every-k-th count restarts), the status line per hand, the joint ids the head
gets, a frame without an ego view, a pose-only model, a centre frame repeated by a drop, and stitching around a frame
without hands."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine import streaming_engine
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.touch_model import TouchAnything


@pytest.fixture(scope="module")
def model() -> TouchAnything:
    torch.manual_seed(3)
    return TouchAnything(preset("nano")).eval()


def stream(model: TouchAnything, frames: int, seed: int = 0, valid: np.ndarray | None = None) -> list[Snapshot]:
    rng = np.random.default_rng(seed)
    size = model.config.image_size
    images = {v: rng.integers(0, 256, (frames, size, size, 3), dtype=np.uint8) for v in VIEW_NAMES}
    joints = (rng.normal(0, 2, (frames, 42, 3)) + [0, 0, 40]).astype(np.float32)
    valid = np.ones((frames, 2), bool) if valid is None else valid
    return [Snapshot(i, i * 33_333, {v: images[v][i] for v in VIEW_NAMES}, joints[i], valid[i]) for i in range(frames)]


def run(engine: StreamingEngine, snapshots) -> dict:
    return {p.frame_index: p for s in snapshots for p in engine.step(s)}


def test_latency_is_the_injected_clock_minus_the_capture_time(model):
    snapshots = stream(model, 4)
    engine = StreamingEngine(model, EngineSetting(every=2), clock=lambda: 5.0)  # 5 s = 5 000 000 µs
    got = run(engine, snapshots)
    assert [got[i].latency_ms for i in range(4)] == [(5_000_000 - i * 33_333) / 1000 for i in range(4)]
    assert got[1].held and got[1].latency_ms == pytest.approx(4966.667)
    (none,) = engine.step(dataclasses.replace(snapshots[3], frame_index=7, images={}))
    assert none.pressure is None and none.latency_ms == pytest.approx((5_000_000 - 3 * 33_333) / 1000)


def test_stage_timings_are_milliseconds(model):
    got = run(StreamingEngine(model, EngineSetting()), stream(model, 2))
    timings = got[1].timings_ms
    assert set(timings) == {"preprocess", "encode", "head", "total"}
    assert all(0.0 < value < 60_000 for value in timings.values())
    assert timings["encode"] > 0.01 and timings["head"] > 0.01  # a forward pass takes more than 10 µs
    assert timings["total"] >= timings["preprocess"] + timings["encode"] + timings["head"]


def test_a_window_is_exact_once_every_ideal_frame_is_cached_and_none_lies_before_the_start(model):
    snapshots = stream(model, 24)
    got = run(StreamingEngine(model, EngineSetting()), [s for s in snapshots if s.frame_index != 20])
    assert [i for i, p in sorted(got.items()) if p.window_exact] == [14, 15, 16, 17, 18, 19, 21, 23]
    assert got[13].status == "ok" and got[14].hands_predicted == (True, True)


def test_drain_returns_what_each_output_position_holds_back(model):
    snapshots = stream(model, 20, seed=4)
    assert StreamingEngine(model, EngineSetting()).drain() == []
    newest = StreamingEngine(model, EngineSetting())
    run(newest, snapshots)
    assert newest.drain() == []
    centre = StreamingEngine(model, EngineSetting(output="centre"))
    emitted = run(centre, snapshots)
    assert sorted(emitted) == list(range(14))  # the window ending on 19 has frame 13 at position 4
    drained = centre.drain()
    assert [p.frame_index for p in drained] == list(range(14, 20))
    # Each with the newest-frame output of the window ending on it, from the 15 frames still cached (5–19): only
    # the window ending on 19 has all its ideal frames.
    assert [p.window_exact for p in drained] == [False] * 5 + [True]
    reference = run(StreamingEngine(model, EngineSetting()), snapshots)
    assert np.allclose(drained[-1].pressure, reference[19].pressure, atol=1e-6, equal_nan=True)
    assert centre.drain() == []  # nothing is held twice
    stitched = StreamingEngine(model, EngineSetting(output="stitched"))
    emitted = run(stitched, snapshots)
    assert sorted(emitted) == list(range(6))  # the first window not padded ends on 14; frame 5 is done at 19
    assert [p.frame_index for p in stitched.drain()] == list(range(6, 20))
    assert stitched.drain() == []


def test_reset_forgets_the_cache_and_what_was_emitted(model):
    snapshots = stream(model, 18, seed=6)
    engine = StreamingEngine(model, EngineSetting(output="centre"))
    run(engine, snapshots)
    engine.reset()
    again = run(engine, snapshots[:12])
    fresh = run(StreamingEngine(model, EngineSetting(output="centre")), snapshots[:12])
    assert sorted(again) == sorted(fresh) == list(range(6))
    assert all(np.array_equal(again[i].pressure, fresh[i].pressure, equal_nan=True) for i in fresh)


def test_the_status_names_the_hand_without_a_pose(model):
    valid = np.array([[True, True], [False, True], [True, False], [False, False]])
    got = run(StreamingEngine(model, EngineSetting()), stream(model, 4, valid=valid))
    assert [got[i].status for i in range(4)] == ["ok", "left hand: no pose", "right hand: no pose", "no valid hand pose"]
    assert [got[i].hands_predicted for i in range(4)] == [(True, True), (False, True), (True, False), (False, False)]


def test_after_a_seek_every_kth_frame_counts_from_the_new_start(model):
    snapshots = stream(model, 8, seed=7)
    engine = StreamingEngine(model, EngineSetting(every=3))
    first = run(engine, snapshots[:5])
    again = run(engine, snapshots)  # frame 0 again: a seek
    assert [i for i, p in first.items() if not p.held] == [0, 3]
    assert [i for i, p in again.items() if not p.held] == [0, 3, 6]


def test_timings_are_the_perf_counter_differences_times_a_thousand(model, monkeypatch):
    ticks = iter(np.arange(0.0, 1000.0, 0.5))
    monkeypatch.setattr(streaming_engine.time, "perf_counter", lambda: float(next(ticks)))
    (prediction,) = StreamingEngine(model, EngineSetting()).step(stream(model, 1)[0])
    timings = prediction.timings_ms
    assert set(timings) == {"preprocess", "encode", "head", "total"}
    assert all(value > 0 and value % 500.0 == 0 for value in timings.values()), timings  # steps of 0.5 s


def test_the_head_gets_the_official_joint_ids_of_the_hands_it_predicts(model):
    valid = np.array([[True, True], [False, True], [True, False]])
    engine = StreamingEngine(model, EngineSetting())
    calls = []
    head = engine.runtime.head

    def recording(tokens, joints, joint_ids, positions):
        calls.append(joint_ids.tolist())
        return head(tokens, joints, joint_ids, positions)

    engine.runtime.head = recording
    run(engine, stream(model, 3, valid=valid))
    assert calls == [list(range(42)), list(range(21, 42)), list(range(21))]  # 0–20 left, 21–41 right


def test_a_frame_without_an_ego_view_says_so_in_every_field(model):
    snapshot = stream(model, 1)[0]
    (prediction,) = StreamingEngine(model, EngineSetting()).step(dataclasses.replace(snapshot, images={}))
    assert (prediction.pressure, prediction.hands_predicted, prediction.window_exact, prediction.views_used) == (
        None, (False, False), False, ())


def test_a_pose_only_model_sees_black_frames_whatever_the_cameras_show(model):
    blank = TouchAnything(dataclasses.replace(model.config, blank_images=True)).eval()
    blank.load_state_dict(model.state_dict())
    snapshots = stream(model, 3, seed=8)
    black = [dataclasses.replace(s, images={v: np.zeros_like(i) for v, i in s.images.items()}) for s in snapshots]
    got = run(StreamingEngine(blank, EngineSetting()), snapshots)
    want = run(StreamingEngine(model, EngineSetting()), black)
    assert all(np.allclose(got[i].pressure, want[i].pressure, atol=1e-6, equal_nan=True) for i in range(3))


def test_the_centre_output_emits_each_frame_once_when_a_drop_repeats_the_centre_frame(model):
    snapshots = [s for s in stream(model, 24, seed=9) if s.frame_index != 15]
    engine = StreamingEngine(model, EngineSetting(output="centre"))
    emitted = [p.frame_index for s in snapshots for p in engine.step(s)] + [p.frame_index for p in engine.drain()]
    assert emitted == sorted(set(emitted))  # at 21 the centre is 14 again (15 missing, 14 and 16 tie): not re-emitted
    assert 15 not in emitted and emitted[:3] == [0, 1, 2]


def test_stitching_a_frame_without_hands_leaves_the_other_frames_as_they_were(model):
    valid = np.ones((26, 2), bool)
    valid[10] = False  # frame 10: no hand; it shares 7 windows with frame 12
    valid[:, 1] = False  # the right hand never has a pose
    snapshots = stream(model, 26, seed=10, valid=valid)
    every = stream(model, 26, seed=10, valid=np.column_stack([np.ones(26, bool), np.zeros(26, bool)]))
    got, want = (run(StreamingEngine(model, EngineSetting(output="stitched")), s) for s in (snapshots, every))
    assert sorted(got) == sorted(want) == list(range(12))
    assert got[10].hands_predicted == (False, False) and got[0].hands_predicted == (True, False)  # 0: in one window only
    assert all(np.allclose(got[i].pressure, want[i].pressure, atol=1e-6, equal_nan=True) for i in range(12) if i != 10)
