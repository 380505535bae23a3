"""After a seek the engine holds nothing of the frames before it: for every output mode (newest, centre, stitched,
every k-th frame) the predictions from the seek point on equal, by value, those of a fresh engine fed from the seek
point (an independent run, not the same state). A frame index that does not increase is a seek to the engine itself
(`StreamingEngine.step`); a forward jump is not, so the replay session resets the engine on every seek
(`EngineSession._restart`)."""
from __future__ import annotations

import time

import numpy as np
import pytest
import torch

from tests.app.test_figures_restart import FIRST, paused_session, step_to  # noqa: F401 - a fixture and its helper
from tests.inference.test_streaming import random_stream, snapshot
from tests.timing.test_dashboard import wait_for
from touchanything.app.sessions.bundled import bundled_models
from touchanything.app.sessions.engine_choice import build_engine, choose
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.touch_model import TouchAnything

FIRST_RUN, SEEK, END = 22, 6, 22
"""Frames 0 … 21, then a seek back to frame 6 and on to 21."""


@pytest.fixture(scope="module")
def model() -> TouchAnything:
    torch.manual_seed(4)
    return TouchAnything(preset("nano")).eval()


@pytest.fixture(scope="module")
def stream(model) -> dict:
    return random_stream(model.config.image_size, FIRST_RUN, seed=9)


def steps(engine: StreamingEngine, stream: dict, frames) -> list[list]:
    """Per step, the predictions it returned; the drain's last."""
    out = [engine.step(snapshot(stream, i)) for i in frames]
    return [*out, engine.drain()]


def same(a: list[list], b: list[list]) -> None:
    """Step by step the same frames, held flags, hands and maps."""
    assert [[p.frame_index for p in step] for step in a] == [[p.frame_index for p in step] for step in b]
    for step_a, step_b in zip(a, b):
        for p, q in zip(step_a, step_b):
            assert (p.held, p.hands_predicted, p.window_exact) == (q.held, q.hands_predicted, q.window_exact), p.frame_index
            np.testing.assert_allclose(p.pressure, q.pressure, rtol=0, atol=1e-6, err_msg=f"frame {p.frame_index}")


CONFIGS = {"newest": EngineSetting(), "centre": EngineSetting(output="centre"), "stitched": EngineSetting(output="stitched"),
           "every 3": EngineSetting(every=3)}


@pytest.mark.parametrize("name", list(CONFIGS))
def test_after_a_backward_seek_the_engine_equals_a_fresh_one(model, stream, name):
    config = CONFIGS[name]
    engine = StreamingEngine(model, config)
    before = [p for i in range(FIRST_RUN) for p in engine.step(snapshot(stream, i))]
    assert before  # the engine was well into the stream: its window, its stitching sums, its k-th frame count
    seeked = steps(engine, stream, range(SEEK, END))
    fresh = steps(StreamingEngine(model, config), stream, range(SEEK, END))
    same(seeked, fresh)
    emitted = [[p.frame_index for p in step] for step in seeked]
    if name == "centre":  # resumes at once: the sought frame first (padded window), then 6 frames behind
        assert emitted[0] == [SEEK] and emitted[1:7] == [[]] * 6 and emitted[7] == [SEEK + 1]
    if name == "every 3":  # the count restarts at the sought frame: computed there, held for the next two
        assert [step[0].held for step in seeked[:-1]] == [i % 3 != 0 for i in range(END - SEEK)]
    if name == "stitched":  # every frame from the seek point on, once
        assert sorted(i for step in emitted for i in step) == list(range(SEEK, END))


def test_reset_forgets_everything_before_a_forward_jump(model, stream):
    """A jump forward is not a seek to the engine (the index increases): `reset()` is what a session calls."""
    for config in CONFIGS.values():
        engine = StreamingEngine(model, config)
        for i in range(8):
            engine.step(snapshot(stream, i))
        engine.reset()
        same(steps(engine, stream, range(12, END)), steps(StreamingEngine(model, config), stream, range(12, END)))


def test_the_replay_session_resets_the_engine_on_a_forward_seek(paused_session, episode_dir):  # noqa: F811 - the imported fixture
    """Paused replay of the conftest episode with the bundled pico model: frames 0 … 4, then a seek forward to 12 and
    steps to 15. Without the reset the window at 12 would take the cached frames 0 … 4 for its earlier positions."""
    session = paused_session
    for frame in range(5):
        step_to(session, frame)
    session.seek(12)  # paused: the sought frame is released
    wait_for(lambda: (p := session.state().prediction) is not None and p.frame_index == 12, "the sought frame")
    shown = {12: session.state().prediction.pressure}
    for frame in range(13, 16):
        shown[frame] = step_to(session, frame)[0]
    fresh = build_engine(choose(bundled_models()[FIRST]))  # the checkpoint loaded again
    expected = {}
    with open_episode(episode_dir) as episode:
        for snap in ReplaySource(episode, ReplayConfig(speed=None, start_frame=12)):
            if snap.frame_index > 15:
                break
            expected.update({p.frame_index: p.pressure for p in fresh.step(snap)})
    assert sorted(expected) == [12, 13, 14, 15]
    for frame in range(12, 16):
        np.testing.assert_allclose(shown[frame], expected[frame], rtol=0, atol=1e-6, err_msg=f"frame {frame}")


def test_a_frame_taken_before_a_seek_never_counts_in_the_new_figures(paused_session, episode_dir):  # noqa: F811
    """The source thread may deliver a frame it took before a seek after the figures restarted (a dashboard test
    under load counted 2 metric frames after a paused seek where 1 was right). The session drops it: with the
    seek done in its two halves, frame 9 handed over between them never shows, never reaches the engine and
    never counts; the sought frame 20 then counts as the first frame."""
    session = paused_session
    for frame in range(5):
        step_to(session, frame)
    with open_episode(episode_dir) as episode:
        late = next(iter(ReplaySource(episode, ReplayConfig(speed=None, start_frame=9))))
    session.restart(sought=20)  # what ReplaySession.seek(20) does before moving the source
    session.submit(late)
    time.sleep(1.0)  # the engine predicts a pico frame in well under a second: time for frame 9 to show if kept
    state = session.state()
    assert state.prediction is None and state.metric_frames == 0 and state.snapshot.frame_index == 4
    session.source.seek(20)
    wait_for(lambda: (p := session.state().prediction) is not None and p.frame_index == 20, "the sought frame")
    assert session.state().metric_frames == 1
    step_to(session, 21)
    assert session.state().metric_frames == 2
