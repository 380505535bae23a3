"""Every figure restarts where docs/dashboard.md says it does: after a switch of the model (or the views, the
rate, a seek) the cumulative metrics count only the frames since, and right after a switch while paused the
session shows nothing of the old model's (no prediction, no metrics) until the new one predicts. A replay
session on a small episode (tests/conftest.py), stepped frame by frame while paused, without a window."""
from __future__ import annotations

import numpy as np
import pytest

from tests.timing.test_dashboard import wait_for
from touchanything.app.sessions.bundled import bundled_models
from touchanything.app.sessions.engine_choice import build_engine, choose
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.devices.episodes.episode_loader import open_episode

FIRST, SECOND = "pico", "nano_pose_only"
"""A small model with images, then a pose-only model (trained on black frames: it uses no view)."""


@pytest.fixture
def paused_session(episode_dir):
    """A replay session of the 40-frame conftest episode with `FIRST`, paused before its first frame."""
    if not {FIRST, SECOND} <= set(bundled_models()):
        pytest.skip(f"the bundled models {FIRST} and {SECOND} are not in models/")
    choice = choose(bundled_models()[FIRST])
    with open_episode(episode_dir) as episode:
        session = ReplaySession(episode, build_engine(choice), choice)
        session.pause()
        session.start()
        try:
            yield session
        finally:
            session.close()


def step_to(session: ReplaySession, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """Step once and wait for the prediction of `frame`; its (predicted, measured) maps."""
    session.step()
    wait_for(lambda: (p := session.state().prediction) is not None and p.frame_index == frame, f"the prediction of frame {frame}")
    state = session.state()
    return state.prediction.pressure, state.truth


def by_hand(pairs: list[tuple[np.ndarray, np.ndarray]]) -> dict[str, float]:
    """Volumetric IoU (Σ min / Σ max) and contact IoU (cells above 0.1 in both / in either) over the frames of
    `pairs`, on the measured map's cells (the official protocol's mask)."""
    predicted = np.stack([p for p, _ in pairs]).astype(np.float64)
    measured = np.stack([m for _, m in pairs]).astype(np.float64)
    inside = ~np.isnan(measured)
    p, m = np.where(inside, np.nan_to_num(predicted), 0.0), np.where(inside, measured, 0.0)
    return {"volumetric_iou": np.minimum(p, m).sum() / np.maximum(p, m).sum(),
            "contact_iou": ((p > 0.1) & (m > 0.1)).sum() / ((p > 0.1) | (m > 0.1)).sum()}


def test_a_model_switch_restarts_the_figures_and_shows_nothing_of_the_old_model(paused_session):
    session = paused_session
    before = [step_to(session, frame) for frame in range(5)]
    state = session.state()
    assert state.metric_frames == 5 and state.views_used == VIEW_NAMES
    assert state.cumulative["volumetric_iou"] == pytest.approx(by_hand(before)["volumetric_iou"], abs=1e-9)
    shown_truth = state.truth

    session.set_model(SECOND, "torch-fp32")
    wait_for(lambda: session.state().model.startswith(SECOND), "the new model")
    state = session.state()  # paused: nothing has run since the switch
    assert state.prediction is None and state.metric_frames == 0
    assert state.facts is not None and not state.facts.predicted and state.facts.rolling is None and state.cumulative is None
    assert np.isnan(state.facts.contact("predicted")).all()  # the predicted lamps are dark
    assert np.array_equal(state.truth, shown_truth, equal_nan=True)  # the frame on screen keeps its measurement
    assert state.history["volumetric_iou"].size == 0 and state.history["latency_ms"].size == 0
    assert state.views_used == ()  # a pose-only model takes nothing from any view

    after = [step_to(session, frame) for frame in range(5, 11)]
    state = session.state()
    assert state.metric_frames == 6  # the frames since the switch only (not 11)
    expected = by_hand(after)
    for key in ("volumetric_iou", "contact_iou"):
        assert state.cumulative[key] == pytest.approx(expected[key], abs=1e-9), key
    assert by_hand(before + after)["volumetric_iou"] != pytest.approx(expected["volumetric_iou"], abs=1e-6)


def test_a_views_switch_a_seek_and_a_rate_switch_restart_the_figures_and_a_threshold_keeps_the_maps(paused_session):
    session = paused_session
    for frame in range(3):
        step_to(session, frame)
    session.set_views(("ego",))
    state = session.state()
    assert state.prediction is None and state.metric_frames == 0 and state.views_used == ("ego",)
    after = [step_to(session, frame) for frame in range(3, 7)]
    state = session.state()
    assert state.metric_frames == 4 and state.prediction.views_used == ("ego",)
    assert state.cumulative["volumetric_iou"] == pytest.approx(by_hand(after)["volumetric_iou"], abs=1e-9)

    shown = state.prediction
    session.set_threshold(0.2)  # the same model's prediction of the same frame: it stays, judged afresh
    state = session.state()
    assert state.prediction is shown and state.metric_frames == 0 and np.isnan(state.cumulative["volumetric_iou"])

    session.seek(20)  # paused: the sought frame is released, and is the first the metrics count
    wait_for(lambda: (p := session.state().prediction) is not None and p.frame_index == 20, "the sought frame")
    assert session.state().metric_frames == 1

    session.set_rate(2)
    wait_for(lambda: session.state().setting.endswith("/every2"), "predicting every 2nd frame")
    state = session.state()
    assert state.prediction is None and state.metric_frames == 0
    for frame in (21, 22, 23):
        step_to(session, frame)
    assert session.state().metric_frames == 3
