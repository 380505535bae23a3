"""The dashboard as a user drives it, on a real X server (Xvfb): it renders only when something changes
(near idle when paused, capped while playing), a seek while paused shows the sought frame everywhere, the
demo loops, a replay's Record button says why it records nothing, and the sources table's columns keep
apart. Each dashboard runs in a fresh process (one per process, as for a user)."""
from __future__ import annotations

import time
from pathlib import Path

import dearpygui.dearpygui as dpg

from tests.timing.test_dashboard import NANO, drive_in_dashboard, in_fresh_process, wait_for
from touchanything.app.sessions.bundled import sample_episodes
from touchanything.app.sessions.replay_runs import replay_in_dashboard
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.viz.dashboard.dashboard import IDLE_PERIOD_S, MAX_FPS, Dashboard
from touchanything.viz.dashboard.dashboard_controls import DEVICE_COLUMNS


def render_rate(dashboard: Dashboard, seconds: float) -> float:
    """Frames rendered per second over about `seconds`, divided by the time that really went by (a busy CPU
    wakes the sleeper late: dividing by `seconds` would then overstate the rate)."""
    frames, began = dashboard.stats.frames, time.monotonic()
    time.sleep(seconds)
    frames, elapsed = dashboard.stats.frames - frames, time.monotonic() - began
    return frames / elapsed


def shown_everywhere(dashboard: Dashboard, session: ReplaySession) -> dict:
    """The frame each part of the screen shows: cameras, maps (the prediction's frame), slider, the text
    beside it, and the sources table's replay row."""
    prediction = dashboard.shown.get("prediction")
    return {"cameras": dashboard.shown["snapshot"].frame_index,
            "maps": None if prediction is None else prediction.frame_index,
            "slider": dpg.get_value("seek"), "frame text": dpg.get_value("frame_text"),
            "sources": session.state().sources[0].detail}


def agree_on(frame: int, frames: int) -> dict:
    return {"cameras": frame, "maps": frame, "slider": frame, "frame text": f"frame {frame} of {frames}",
            "sources": f"frame {frame} of {frames}"}


def drive(session: ReplaySession, dashboard: Dashboard, found: dict) -> None:
    try:
        frames = session.episode.num_frames
        wait_for(lambda: session.state().prediction is not None, "a first prediction")
        found["playing fps"] = render_rate(dashboard, 2.0)
        session.pause()
        time.sleep(0.5)
        cpu = time.process_time()
        found["paused fps"] = render_rate(dashboard, 3.0)
        found["paused cpu"] = (time.process_time() - cpu) / 3.0
        for frame in (120, 180, 227):  # a drag: only the last frame stays on screen
            session.seek(frame)
        wait_for(lambda: shown_everywhere(dashboard, session) == agree_on(227, frames), "the sought frame everywhere")
        time.sleep(1.0)
        found["after seek"] = shown_everywhere(dashboard, session)
        found["metric frames"] = session.state().metric_frames
        session.step()
        wait_for(lambda: shown_everywhere(dashboard, session) == agree_on(228, frames), "the stepped frame everywhere")
        found["after step"] = shown_everywhere(dashboard, session)
        dpg.get_item_callback("record_button")()
        found["record message"] = session.state().message
        found["record enabled"] = dpg.get_item_configuration("record_button")["enabled"]
        found["cells"] = [[(*dpg.get_item_rect_min(f"device_{row}_{column}"), *dpg.get_item_rect_size(f"device_{row}_{column}"),
                            dpg.get_value(f"device_{row}_{column}")) for column in range(len(DEVICE_COLUMNS))]
                          for row in range(len(session.state().sources))]
        found["slider"] = (*dpg.get_item_rect_min("seek"), *dpg.get_item_rect_size("seek"))
        found["frame text rect"] = dpg.get_item_rect_min("frame_text")
    except AssertionError as exc:
        found["error"] = str(exc)
    finally:
        dashboard.close()


def test_the_dashboard_idles_when_paused_and_a_paused_seek_shows_the_frame_everywhere(dashboard_display):
    found = in_fresh_process(drive_in_dashboard, sample_episodes()[0], NANO, drive)
    assert "error" not in found, found
    print(f"render rate playing {found['playing fps']:.1f} fps, paused {found['paused fps']:.1f} fps "
          f"(process CPU {100 * found['paused cpu']:.0f} % of a core)")
    # Paused, frames come only at the idle rate plus the odd table change (before: as fast as the CPU allowed).
    assert found["paused fps"] <= 2.5 / IDLE_PERIOD_S, found["paused fps"]
    assert found["playing fps"] <= MAX_FPS * 1.1, found["playing fps"]
    assert found["after seek"] == agree_on(227, 300) and found["metric frames"] == 1, found
    assert found["after step"] == agree_on(228, 300)
    assert found["record enabled"] and found["record message"].startswith("Record is for the live rig")
    for row in found["cells"]:
        for (x, _, width, _, text), (next_x, *_) in zip(row, row[1:]):
            assert x + width <= next_x, f"{text!r} runs into the next column: {row}"
    x, _, width, _ = found["slider"]
    assert found["frame text rect"][0] >= x + width, "the frame number is drawn over the slider"


def looped_demo(episode: Path) -> dict:
    dashboard = replay_in_dashboard(episode, NANO, max_frames=240, loop=True)
    state = dashboard.session.state()
    return {"passes": dashboard.session.passes, "paused": state.playback.paused,
            "camera updates": len(dashboard.stats.camera_lag_ms), "frames": state.playback.frames}


def test_the_demo_loops_the_episode_until_closed(dashboard_display, episode_dir):
    found = in_fresh_process(looped_demo, episode_dir)
    assert found["frames"] == 40
    assert found["passes"] >= 2 and found["camera updates"] > 60 and not found["paused"], found


def test_sources_the_episode_does_not_have_read_not_in_this_scene(tmp_path):
    """A plain video (ego only, no glove, no pose file): its missing sources are not failures."""
    from conftest import write_episode
    from touchanything.viz.dashboard.dashboard_controls import _device_cells

    folder = write_episode(tmp_path / "Home" / "task" / "20260101_000000_000", frames=4, views=("ego",))
    (folder / "wilor_hands.json").unlink()
    with open_episode(folder) as episode:
        session = ReplaySession(episode, None, NANO)
        cells = {row.name: _device_cells(row) for row in session.source_rows(session.source.snapshot(0))}
    assert cells["ego"][1] == "ok"
    for name in ("wrist_left", "wrist_right", "pose"):
        assert cells[name][1] == "not in this scene", cells
    assert "DOWN" not in str(cells)
