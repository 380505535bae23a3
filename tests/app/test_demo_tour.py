"""The demo tours the bundled sample's episodes: in the dashboard's session one after the other, over and over; in
the headless summary each episode and the official overall (a mean over trajectories, lamps pooled)."""
from __future__ import annotations

import time
from pathlib import Path

import pytest

from conftest import write_episode
from touchanything.app.commands.demo_command import tour_order
from touchanything.app.sessions.bundled import sample_episodes
from touchanything.app.sessions.engine_choice import choose, default_checkpoint
from touchanything.app.sessions.replay_export import ReplaySummary, tour_lines
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.devices.episodes.episode_loader import open_episode


def test_the_tour_shows_where_the_model_is_right_first():
    assert [p.parents[1].name for p in tour_order(sample_episodes())] == ["Workbench", "Office", "Home"]
    other = [Path("/d/Zoo/t/1"), Path("/d/Home/t/1"), Path("/d/Attic/t/1")]
    assert tour_order(other) == [Path("/d/Home/t/1"), Path("/d/Attic/t/1"), Path("/d/Zoo/t/1")]


def test_the_overall_is_the_mean_over_episodes_and_the_lamps_pooled():
    a = ReplaySummary(frames=10, predicted=10, metrics={"volumetric_iou": 0.2, "contact_iou": None, "mae": 0.1},
                      lamps_agree=[8, 5], lamps_judged=[10, 10])
    b = ReplaySummary(frames=30, predicted=30, metrics={"volumetric_iou": 0.6, "contact_iou": 0.5, "mae": 0.3},
                      lamps_agree=[30, 0], lamps_judged=[30, 0])
    none = ReplaySummary(frames=5, metrics=None)  # no ground truth: not in the mean
    lines = tour_lines([a, b, none])
    assert lines[0] == "overall   3 episodes, 45 frames"
    assert lines[1] == ("metrics   mean over the 2 episodes with a prediction and ground truth: volumetric_iou 0.400, "
                        "contact_iou 0.500, mae 0.200")
    # (8 + 30 + 5) / (10 + 30 + 10) = 86 %; left 38 of 40, right 5 of 10
    assert lines[2].startswith("contact   lamps agree on 86.0 % (left 95.0 % of 40 frames, right 50.0 % of 10;")


def test_the_session_plays_its_episodes_in_turn_over_and_over(tmp_path):
    paths = [write_episode(tmp_path / "Home" / "a" / "1", frames=12, seed=1),
             write_episode(tmp_path / "Office" / "b" / "2", frames=9, seed=2)]
    with open_episode(paths[0]) as first, open_episode(paths[1]) as second:
        session = ReplaySession(first, None, choose(default_checkpoint()), tour=[second])
        session.set_speed(4.0)
        session.start()
        try:
            seen, deadline = [], time.monotonic() + 30
            while time.monotonic() < deadline and seen[-3:] != [0, 1, 0]:
                if not seen or seen[-1] != session.index:
                    seen.append(session.index)
                    if session.index == 1:
                        assert session.episode is second and session.truth.shape[0] == 9
                        row = session.source_rows(None)[0]  # (no frame read here: the player thread decodes)
                        assert row.detail == "episode 2 of 2, frame - of 9", row
                time.sleep(0.01)
        finally:
            session.close()
    assert seen[-3:] == [0, 1, 0] and session.passes >= 3, seen


@pytest.mark.parametrize("loop", [False, True])
def test_one_episode_without_a_tour_plays_as_before(episode_dir, loop):
    with open_episode(episode_dir) as episode:
        session = ReplaySession(episode, None, choose(default_checkpoint()), loop=loop)
        assert session.episodes == [episode] and session.source.config.loop is loop
        assert session.source.config.hold_at_end is not loop
