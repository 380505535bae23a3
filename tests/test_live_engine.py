"""Live mode: a real-time 10 s replay through the latest-wins engine thread.

A slow engine (the `small` preset, three views: well under 30 frames/s on these CPUs) must drop frames
while the latency of what it delivers stays bounded; a fast one (nano, ego only) keeps up: on a noisy
2-core machine a scheduling stall may cost it a frame or two, never a backlog.
"""
from __future__ import annotations

import time

import numpy as np
import pytest
import torch

from touchanything.app.sessions.bundled import sample_episodes
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.devices.snapshot import Snapshot
from touchanything.inference.engine.engine_config import EngineConfig
from touchanything.inference.engine.live_engine import LiveEngine
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.touch_model import TouchAnything


def live_replay(engine: StreamingEngine, views: tuple[str, ...]) -> tuple[LiveEngine, list]:
    delivered = []
    with open_episode(sample_episodes()[0]) as episode:
        source = ReplaySource(episode, ReplayConfig(speed=1.0, views=views))
        with LiveEngine(engine, on_prediction=delivered.append) as live:
            for snapshot in source:
                live.submit(snapshot)
            deadline = time.monotonic() + 5
            while not (live.idle() and live.stats.processed + live.stats.dropped == live.stats.submitted):
                assert time.monotonic() < deadline, "the engine did not catch up"
                time.sleep(0.01)
    return live, delivered


def test_a_slow_engine_drops_frames_and_its_latency_stays_bounded():
    torch.manual_seed(0)
    engine = StreamingEngine(TouchAnything(preset("small")).eval(), EngineConfig())
    live, delivered = live_replay(engine, ("ego", "wrist_left", "wrist_right"))
    assert live.stats.submitted == 300
    assert live.stats.dropped > 30, live.stats
    latency = np.array([p.latency_ms for p in delivered])
    step = np.median([p.timings_ms["total"] for p in delivered])
    third = len(latency) // 3
    print(f"slow engine: {step:.0f} ms/step, {live.stats.dropped} of 300 dropped, "
          f"latency first third {latency[:third].mean():.0f} ms, last third {latency[-third:].mean():.0f} ms")
    assert latency[-third:].mean() < latency[:third].mean() * 1.5 + 50
    assert latency.max() < 4 * step + 250


def test_a_fast_engine_keeps_up():
    torch.manual_seed(0)
    engine = StreamingEngine(TouchAnything(preset("nano")).eval(), EngineConfig(views=("ego",)))
    live, delivered = live_replay(engine, ("ego",))
    assert live.stats.dropped <= 9, live.stats
    assert len(delivered) == live.stats.processed == 300 - live.stats.dropped
    indices = [p.frame_index for p in delivered]
    assert indices == sorted(set(indices)) and indices[-1] == 299


def test_an_engine_error_is_kept_and_raised_on_stop():
    torch.manual_seed(0)
    engine = StreamingEngine(TouchAnything(preset("nano")).eval(), EngineConfig())
    broken = Snapshot(0, 0, {"ego": np.zeros((4, 4, 3, 2), np.uint8)}, np.zeros((42, 3), np.float32), np.ones(2, bool))
    live = LiveEngine(engine).start()
    live.submit(broken)
    deadline = time.monotonic() + 10
    while live.error is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert live.error is not None
    with pytest.raises(type(live.error)):
        live.stop()
