"""The dashboard's panels never disagree, on a real X server (Xvfb): for a hand without a pose the predicted
map's title, the map itself and the lamps all say so; the metrics table and the plot's legends show the same
values (also right after a threshold change restarts the metrics); paused, the engine's row and the rates say
"paused"; a message never moves the controls, and the Record button's message shows after a screenshot's.
One driven replay of the conftest episode (its right hand has no pose at frames 3, 10, 17, …)."""
from __future__ import annotations

import threading
import time
from pathlib import Path

import cv2
import dearpygui.dearpygui as dpg
import numpy as np

from tests.timing.test_dashboard import NANO, in_fresh_process, wait_for
from touchanything.app.sessions.engine_choice import build_engine
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.view_sets import VIEW_LABELS
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.viz.contact import OFF, ON, UNKNOWN
from touchanything.viz.dashboard.dashboard import CELL, MAPS, Dashboard, DashboardConfig
from touchanything.viz.dashboard.dashboard_controls import DEVICE_COLUMNS, TEXT_WIDTH
from touchanything.viz.pressure_panel import BACKGROUND, MAP_GAP, MAP_TITLES

CONTROLS = ("play_button", "seek", "view_ego", "model", "rate", "threshold", "record_button", "screenshot_button",
            "rolling_temporal_accuracy", "device_0_0")
"""The controls (and the tables below them) whose place must not move."""
LONG_MESSAGE = "a long status message that wraps " * 8


def _places() -> dict[str, tuple[int, int]]:
    return {tag: tuple(dpg.get_item_rect_min(tag)) for tag in CONTROLS}


def _metric_cells(dashboard: Dashboard) -> dict[str, str]:
    """What the table and the plot's legends show of the rolling metrics."""
    legends = dashboard.plots.legends
    return {"table C-IoU": dpg.get_value("rolling_contact_iou"), "table V-IoU": dpg.get_value("rolling_volumetric_iou"),
            "legend C-IoU": dpg.get_item_configuration(legends["contact_iou"])["text"],
            "legend V-IoU": dpg.get_item_configuration(legends["volumetric_iou"])["text"]}


def _rows() -> dict[str, list[str]]:
    """The sources table as shown: name → the row's cells."""
    rows = {}
    for row in range(10):
        if dpg.get_item_configuration(f"device_row_{row}")["show"]:
            cells = [dpg.get_value(f"device_{row}_{column}") for column in range(len(DEVICE_COLUMNS))]
            rows[cells[0]] = cells
    return rows


def _settle(dashboard: Dashboard) -> None:
    """A few table refreshes (every 0.1 s), then two frames rendered after them: on a busy CPU the render loop
    may fall behind the sleep; the frames say it went round with what the sleep allowed for."""
    time.sleep(0.6)
    frames = dashboard.stats.frames
    wait_for(lambda: dashboard.stats.frames >= frames + 2, "two more rendered frames")


def drive(session: ReplaySession, dashboard: Dashboard, found: dict) -> None:
    try:
        wait_for(lambda: (p := session.state().prediction) is not None and p.frame_index >= 12, "frames with contact")
        session.pause()
        _settle(dashboard)
        found["paused"] = {"rows": _rows(), "performance": dpg.get_value("performance_text")}
        found["steady"] = _metric_cells(dashboard)
        dpg.get_item_callback("threshold")("threshold", 0.3)
        _settle(dashboard)
        found["after threshold"] = _metric_cells(dashboard)
        session.seek(10)
        wait_for(lambda: getattr(dashboard.shown.get("prediction"), "frame_index", None) == 10, "frame 10 on screen")
        _settle(dashboard)
        found["title"] = dpg.get_value("title_predicted")
        found["posed"] = session.state().facts.posed
        found["rect"] = dashboard.panel_rects["predicted"]
        found["lamps"] = [[tuple(round(255 * c) for c in dpg.get_item_configuration(lamp)["fill"]) for lamp in hand]
                          for hand in dashboard.lamps.lamps]  # dearpygui gives colours on [0, 1]
        found["verdicts"] = [dpg.get_item_configuration(v)["text"] for v in dashboard.lamps.verdicts]
        found["at frame 10"] = _metric_cells(dashboard)
        found["vocabulary"] = {"views": [dpg.get_item_configuration(f"view_{v}")["label"] for v in VIEW_NAMES],
                               "titles": {name: dpg.get_value(f"title_{name}") for name in MAP_TITLES}}
        before = _places()
        dpg.get_item_callback("screenshot_button")()
        wait_for(lambda: dashboard.saved_screenshots, "the screenshot")  # of frame 10, still paused
        found["screenshot"] = dashboard.saved_screenshots[0]
        wait_for(lambda: dpg.get_value("message_text").startswith("screenshot saved"), "the screenshot's message")
        found["with the screenshot's message"] = _places()
        dpg.get_item_callback("record_button")()
        _settle(dashboard)
        found["record message"] = dpg.get_value("message_text")
        session.message = LONG_MESSAGE
        wait_for(lambda: dpg.get_value("message_text") == LONG_MESSAGE, "the long message")
        _settle(dashboard)
        found["with a long message"] = _places()
        found["without a message"] = before
        found["message size"] = tuple(dpg.get_item_rect_size("message_text"))
        found["model text"] = (tuple(dpg.get_item_rect_min("model_text")), tuple(dpg.get_item_rect_size("model_text")))
        found["viewport width"] = dpg.get_viewport_client_width()
    except AssertionError as exc:
        found["error"] = str(exc)
    finally:
        dashboard.close()


def driven(episode_dir: Path, screenshots: Path) -> dict:
    found: dict = {}
    with open_episode(episode_dir) as episode:
        session = ReplaySession(episode, build_engine(NANO), NANO).start()
        dashboard = Dashboard(session, DashboardConfig(screenshot_dir=screenshots))
        thread = threading.Thread(target=drive, args=(session, dashboard, found), daemon=True)
        thread.start()
        dashboard.run()
        thread.join(5)
    return found


def legend_agrees(cells: dict[str, str]) -> bool:
    """The legend shows the table's value (two decimals instead of three), or both say n/a. Both round the same
    number: 0.02496 is "0.025" in the table and "0.02" in the legend, so the legend is the value the table's
    three decimals allow (within half a unit of its second decimal, and of the table's third), not the table's
    string rounded again."""
    for name in ("C-IoU", "V-IoU"):
        table, legend = cells[f"table {name}"], cells[f"legend {name}"].removeprefix(f"{name} ")
        if "n/a" in (table, legend):
            if table != legend:
                return False
        elif not (len(legend.partition(".")[2]) == 2 and abs(float(legend) - float(table)) <= 0.005 + 0.0005 + 1e-9):
            return False
    return True


def test_the_panels_agree_and_messages_never_move_the_controls(dashboard_display, episode_dir, tmp_path):
    found = in_fresh_process(driven, episode_dir, tmp_path / "shots")
    assert "error" not in found, found["error"]

    # paused: no stale rates
    rows = found["paused"]["rows"]
    assert "paused" in rows["engine"][1] and rows["engine"][2] == "", rows["engine"]
    assert rows["replay"][2] == "", rows["replay"]
    assert found["paused"]["performance"].endswith("engine paused") and "latency" not in found["paused"]["performance"]

    # the metrics table and the plot's legends show one record
    assert legend_agrees(found["steady"]) and found["steady"]["table C-IoU"] != "n/a", found["steady"]
    assert found["after threshold"] == {"table C-IoU": "n/a", "table V-IoU": "n/a", "legend C-IoU": "C-IoU n/a",
                                        "legend V-IoU": "V-IoU n/a"}  # the metrics restarted: nothing stale
    assert legend_agrees(found["at frame 10"]), found["at frame 10"]

    # a hand without a pose: the title, the map and the lamps say so
    assert found["posed"] == (True, False)
    assert found["title"] == f"{MAP_TITLES['predicted']} (no pose: right)"
    x, y, width, height = found["rect"]
    image = cv2.imread(str(found["screenshot"]))[y:y + height, x:x + width, ::-1].astype(int)
    assert image.shape[:2] == (MAPS[1], MAPS[0])
    size = 21 * CELL
    left, right = image[:, :size], image[:, size + MAP_GAP:2 * size + MAP_GAP]
    background = np.all(np.abs(right - BACKGROUND) < 8, axis=-1)
    assert background.mean() > 0.95, "the unposed hand is drawn as a map"  # background, with "no pose" written on it
    assert not np.all(np.abs(left - BACKGROUND) < 8, axis=-1).mean() > 0.5, "the posed hand is not drawn"
    assert found["lamps"][1][0] == (*UNKNOWN, 255) and found["verdicts"][1] == ""  # right: predicted contact unknown
    assert found["lamps"][1][1] in ((*ON, 255), (*OFF, 255))  # its measured lamp is known

    # one vocabulary
    assert found["vocabulary"]["views"] == [VIEW_LABELS[v] for v in VIEW_NAMES]
    for name, title in found["vocabulary"]["titles"].items():
        assert title.startswith(MAP_TITLES[name]), (name, title)

    # messages: never move the controls; the last button's message shows
    assert found["with the screenshot's message"] == found["without a message"]
    assert found["with a long message"] == found["without a message"]
    assert found["record message"].startswith("Record is for the live rig")
    assert found["message size"][0] <= TEXT_WIDTH  # wrapped, not cut at the window's edge
    (x, _), (width, _) = found["model text"]
    assert x + width <= found["viewport width"], found["model text"]
