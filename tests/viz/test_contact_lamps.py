"""The contact lamps of the comparison video, the dashboard and the Rerun recording against hand-made maps whose
contact is known by construction (the official rule per hand: at least 8 of its 151 tactile cells strictly above
0.1): 20 cells at 0.5 and 8 cells at 0.15 are contact; 7 cells at 0.5 and a map of zeros are not. The expected
lamps come from that construction, never from `hand_contact` or the facts' own record."""
from __future__ import annotations

import numpy as np
import pytest

from helpers.rerun_reading import recording_rows
from touchanything.core.snapshot import Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.viz.comparison_video import CAMERA_HEIGHT, PANEL_HEIGHT
from touchanything.viz.contact import lamp_centre
from touchanything.viz.frame_facts import frame_facts
from touchanything.viz.replay_frame import ReplayFrameRenderer
from touchanything.viz.rerun_recording import RerunRecording, RerunTarget

LAYOUT = TactileLayout.default()
TACTILE = LAYOUT.valid & ~LAYOUT.bend


def pressed(counts: tuple[int, int], values: tuple[float, float]) -> np.ndarray:
    """(2, 21, 21): 0 on the layout, NaN outside, values[h] on the first counts[h] tactile cells of hand h."""
    grid = np.where(LAYOUT.valid, 0.0, np.nan).astype(np.float32)
    for h in range(2):
        rows, cols = np.nonzero(TACTILE[h])
        grid[h, rows[:counts[h]], cols[:counts[h]]] = values[h]
    return grid


PREDICTED = pressed((20, 7), (0.5, 0.5))
"""left: 20 cells at 0.5 → contact; right: 7 cells at 0.5 → no contact (7 < 8)."""
MEASURED = pressed((0, 8), (0.0, 0.15))
"""left: all zeros → no contact; right: 8 cells at 0.15 → contact."""
KNOWN = {"predicted": (True, False), "measured": (False, True)}
"""Per kind, [left, right] in contact, from the construction above; neither hand agrees (two "miss")."""
AGREEING = pressed((20, 0), (0.5, 0.0))
"""Measured and predicted alike: left in contact, right not; both "ok"."""


def facts(predicted=PREDICTED, measured=MEASURED):
    return frame_facts(predicted, None, measured, LAYOUT.bend)


def is_green(rgb) -> bool:
    """The lit lamp: clearly green."""
    r, g, b = (float(c) for c in rgb[:3])
    return g > r + 60 and g > b + 60


def is_grey(rgb) -> bool:
    """An unlit lamp: grey (no channel stands out)."""
    r, g, b = (float(c) for c in rgb[:3])
    return max(r, g, b) - min(r, g, b) < 40


def brightness(rgb) -> float:
    return float(sum(float(c) for c in rgb[:3]))


def video_strip(shown: np.ndarray | None, frame_facts_) -> np.ndarray:
    """The lamp panel (the strip's third 480-pixel panel) of a rendered comparison frame."""
    snapshot = Snapshot(0, 0, {"ego": np.full((48, 64, 3), 90, np.uint8)}, np.zeros((42, 3), np.float32), np.zeros(2, bool))
    frame = ReplayFrameRenderer(1).render(snapshot, MEASURED, shown, None, frame_facts_)
    top = CAMERA_HEIGHT + PANEL_HEIGHT
    return frame[top:top + 150, 960:1440].astype(int)


ROW = 150 // 3  # the lamps' row height in the 150-pixel strip


def test_the_video_lamps_light_where_the_hand_made_maps_are_in_contact():
    strip = video_strip(PREDICTED, facts())
    for k, kind in enumerate(("predicted", "measured")):
        for h in range(2):
            x, y = lamp_centre(k, h, 480, ROW)
            colour = strip[y, x]
            assert is_green(colour) == KNOWN[kind][h], (kind, h, colour)
            assert KNOWN[kind][h] or is_grey(colour), (kind, h, colour)
    for h in range(2):  # neither hand agrees: the verdicts are the warm "miss" colour, not the green "ok"
        y = lamp_centre(0, h, 480, ROW)[1]
        verdict = strip[y - 8:y + 8, 480 - 46:480].reshape(-1, 3)
        assert ((verdict[:, 0] > 200) & (verdict[:, 1] < 170)).any() and not is_green(verdict.max(axis=0))
    agreeing = video_strip(AGREEING, facts(AGREEING, AGREEING))
    y = lamp_centre(0, 0, 480, ROW)[1]
    verdict = agreeing[y - 8:y + 8, 480 - 46:480].reshape(-1, 3)
    assert not ((verdict[:, 0] > 200) & (verdict[:, 1] < 170)).any() and (verdict[:, 1] > 200).any()  # "ok" in green


def test_an_unknown_lamp_is_darker_than_a_known_no_contact_one():
    strip = video_strip(None, frame_facts(None, None, MEASURED, LAYOUT.bend))  # no prediction: its lamps unknown
    unknown = strip[lamp_centre(0, 0, 480, ROW)[1], lamp_centre(0, 0, 480, ROW)[0]]
    off = strip[lamp_centre(1, 0, 480, ROW)[1], lamp_centre(1, 0, 480, ROW)[0]]  # measured left: zeros, known "no"
    assert is_grey(off) and not is_green(unknown) and brightness(unknown) < brightness(off) - 30


def test_the_dashboard_lamps_light_where_the_hand_made_maps_are_in_contact():
    """The dashboard's drawn lamps (`ContactLamps`), updated in a dearpygui context (no window is shown)."""
    dpg = pytest.importorskip("dearpygui.dearpygui")
    from touchanything.viz.dashboard.dashboard_drawn import ContactLamps

    dpg.create_context()
    try:
        with dpg.window():
            lamps = ContactLamps(300, 120)
        lamps.update(facts())
        fills = [[[255 * c for c in dpg.get_item_configuration(lamp)["fill"]] for lamp in hand] for hand in lamps.lamps]
        words = [dpg.get_item_configuration(v)["text"] for v in lamps.verdicts]
        lamps.update(facts(AGREEING, AGREEING))
        agreeing = [dpg.get_item_configuration(v)["text"] for v in lamps.verdicts]
    finally:
        dpg.destroy_context()
    for k, kind in enumerate(("predicted", "measured")):
        for h in range(2):
            assert is_green(fills[h][k]) == KNOWN[kind][h], (kind, h, fills[h][k])
            assert KNOWN[kind][h] or is_grey(fills[h][k]), (kind, h, fills[h][k])
    assert words == ["miss", "miss"] and agreeing == ["ok", "ok"]


def test_the_rerun_recording_logs_the_known_contact(tmp_path):
    path = tmp_path / "lamps.rrd"
    recording = RerunRecording(RerunTarget(path), "lamps", {})
    joints, valid = np.zeros((42, 3), np.float32), np.zeros(2, bool)
    for frame, (predicted, measured) in enumerate(((PREDICTED, MEASURED), (AGREEING, AGREEING))):
        frame_record = facts(predicted, measured)
        recording.log_observation(frame, frame / 30, {}, joints, valid, measured, frame_record, {})
        recording.log_prediction(frame, frame / 30, predicted, frame_record, joints, valid, measured, None, None)
    recording.close()
    rows, _ = recording_rows(path)
    assert rows["/contact/predicted"].at("Scalars:scalars", 0) == [1.0, 0.0]
    assert rows["/contact/measured"].at("Scalars:scalars", 0) == [0.0, 1.0]
    assert rows["/contact/predicted"].at("Scalars:scalars", 1) == rows["/contact/measured"].at("Scalars:scalars", 1) == [1.0, 0.0]
