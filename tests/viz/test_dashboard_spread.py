"""The dashboard's spread toggle on a real X server (Xvfb): with a 2-member ensemble (pico and a perturbed pico that
presses) it is enabled and, switched on, the predicted map shows the shown prediction's members' spread on the spread's scale,
titled so; with a single model it is disabled, says why, and the map stays the predicted pressure. One short
replay of the conftest episode (40 frames) per dashboard, each in a fresh process."""
from __future__ import annotations

import time
from pathlib import Path

import dearpygui.dearpygui as dpg
import numpy as np
import torch

from tests.inference.test_ensemble import PICO, ensemble_folder, perturbed_pico
from tests.timing.test_dashboard import drive_in_dashboard, in_fresh_process, wait_for
from touchanything.app.sessions.engine_choice import choose
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.inference.model.checkpoint import read_checkpoint
from touchanything.viz.colormap import PRESSURE_LUT, apply
from touchanything.viz.dashboard.dashboard import CELL, Dashboard
from touchanything.viz.pressure_panel import AXES, MAP_GAP, MAP_TITLES, SPREAD_HIGH, SPREAD_TITLE, unposed_as_nan


def settle(dashboard: Dashboard) -> None:
    """Past a few refreshes, and two frames rendered after them."""
    time.sleep(0.6)
    frames = dashboard.stats.frames
    wait_for(lambda: dashboard.stats.frames >= frames + 2, "two more rendered frames")


def drive(session: ReplaySession, dashboard: Dashboard, found: dict) -> None:
    try:
        wait_for(lambda: (p := session.state().prediction) is not None and p.pressure is not None
                 and any(p.hands_predicted), "a prediction of a posed hand")
        session.pause()
        settle(dashboard)
        found["enabled"] = dpg.get_item_configuration("spread_toggle")["enabled"]
        found["tip"] = dpg.get_value("spread_tip")
        dpg.get_item_callback("spread_toggle")("spread_toggle", True)  # what a click on it does
        settle(dashboard)
        state = session.state()
        found["same record"] = state.prediction is dashboard.shown["prediction"]
        found["prediction"], found["posed"] = state.prediction, state.facts.posed
        found["title"], found["texture"] = dpg.get_value("title_predicted"), dashboard.maps["predicted"].uploaded
    except AssertionError as exc:
        found["error"] = str(exc)
    finally:
        dashboard.close()


def pressing_pico(folder: Path) -> Path:
    """`perturbed_pico` whose cells' logits are raised by LOGIT_SHIFT: it predicts pressure wherever pico predicts
    almost none, so the two members' spread shows on every frame of any episode (pico alone predicts ~0 on the
    conftest episode's synthetic frames, where a spread and a pressure map would both read as empty)."""
    perturbed_pico(folder)
    data = read_checkpoint(folder / "best_model.pth")
    data["model_state_dict"]["decoder.cells.3.bias"] += LOGIT_SHIFT
    torch.save(data, folder / "best_model.pth")
    return folder


LOGIT_SHIFT = 8.0


def cell_colours(image: np.ndarray, hand: int) -> np.ndarray:
    """(21, 21, 3): the colour at the centre of each cell of one hand's map."""
    centres = np.arange(21) * CELL + CELL // 2
    return image[:, hand * (21 * CELL + MAP_GAP):][centres][:, centres]


def test_the_spread_toggle_shows_the_shown_predictions_spread(dashboard_display, episode_dir, tmp_path):
    member = pressing_pico(tmp_path / "member")
    ensemble = choose(ensemble_folder(tmp_path, [member]), members=2, device="cpu")
    found = in_fresh_process(drive_in_dashboard, episode_dir, ensemble, drive)
    assert "error" not in found, found["error"]
    assert found["enabled"] and found["tip"].startswith("show the members' spread"), found["tip"]
    assert found["same record"]
    prediction, posed = found["prediction"], found["posed"]
    assert found["title"].startswith(f"{SPREAD_TITLE} (0–0.5)"), found["title"]
    spread = unposed_as_nan(prediction.spread, posed)
    assert np.nanmax(spread) > 0  # the members differ: the check below is not of an empty map
    for h in np.flatnonzero(posed):
        shown = cell_colours(found["texture"], h)
        np.testing.assert_array_equal(shown, apply(spread[h], PRESSURE_LUT, 0.0, SPREAD_HIGH, AXES))
        assert not np.array_equal(shown, apply(prediction.pressure[h], PRESSURE_LUT, 0.0, 1.0, AXES))


def test_with_one_model_the_spread_toggle_is_disabled(dashboard_display, episode_dir):
    found = in_fresh_process(drive_in_dashboard, episode_dir, choose(PICO / "best_model.pth", device="cpu"), drive)
    assert "error" not in found, found["error"]
    assert not found["enabled"] and found["tip"] == "one model: no spread"
    assert found["prediction"].spread is None
    assert found["title"].startswith(MAP_TITLES["predicted"]), found["title"]  # the toggle has nothing to show
