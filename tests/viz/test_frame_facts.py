"""One record of a frame's derived facts (`viz.frame_facts`): per hand posed, measured, the contact rule and
agreement, the metrics with None for n/a — and the comparison video, the replay summary and the Rerun recording
all show that one record (a hand without a pose: no predicted contact anywhere, a "no pose" map). At its edges, by
value: the per-hand contact rule on its own, which hand counts as posed or measured from its values, the NaN of an
unknown contact, and that the one record every view reads cannot be changed by one of them (frozen)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from helpers.rerun_reading import recording_rows
from touchanything.app.cli import main
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.comparison_video import CAMERA_HEIGHT, PANEL_HEIGHT
from touchanything.viz.contact import UNKNOWN, lamp_centre
from touchanything.viz.frame_facts import FrameFacts, HandFacts, frame_facts, hand_contact, metric_text
from touchanything.viz.pressure_panel import BACKGROUND

LAYOUT = TactileLayout.default()
TACTILE = LAYOUT.valid & ~LAYOUT.bend
"""The cells the contact rule counts: inside the layout, not a bend cell (151 per hand)."""


def pressed(cells_per_hand: tuple[int, int], value: float = 0.5) -> np.ndarray:
    """(2, 21, 21): 0 on the layout, NaN outside, `value` on the first n tactile cells of each hand."""
    grids = np.where(LAYOUT.valid, 0.0, np.nan)
    for h, n in enumerate(cells_per_hand):
        rows, cols = np.nonzero(TACTILE[h])
        grids[h, rows[:n], cols[:n]] = value
    return grids


def test_the_contact_rule_per_hand_at_five_percent_of_its_tactile_cells():
    assert TACTILE.sum(axis=(1, 2)).tolist() == [151, 151]  # so 8 cells (≥ 7.55) make contact, 7 do not
    facts = frame_facts(pressed((8, 7)), (True, True), pressed((7, 8)), LAYOUT.bend)
    assert [(h.contact_predicted, h.contact_measured, h.agree) for h in facts.hands] == [(True, False, False),
                                                                                     (False, True, False)]
    at_threshold = frame_facts(pressed((8, 8), value=0.1), None, None, LAYOUT.bend)  # strictly above 0.1 counts
    assert [h.contact_predicted for h in at_threshold.hands] == [False, False]
    assert [h.contact_predicted for h in frame_facts(pressed((8, 8), 0.25), None, None, LAYOUT.bend, 0.2).hands] == [True, True]


def test_an_unposed_or_unmeasured_hand_is_unknown_not_no_contact():
    measured = pressed((20, 20))
    measured[1] = np.nan  # no glove sample of the right hand
    facts = frame_facts(pressed((20, 20)), (True, False), measured, LAYOUT.bend)
    left, right = facts.hands
    assert (left.posed, left.measured, left.contact_predicted, left.contact_measured, left.agree) == (True, True, True, True, True)
    assert (right.posed, right.measured, right.contact_predicted, right.contact_measured, right.agree) == (
        False, False, None, None, None)  # its values say "contact", but the model did not predict it
    assert facts.unposed == ["right"] and facts.posed == (True, False)
    assert np.array_equal(facts.contact("predicted"), [1.0, np.nan], equal_nan=True)
    nothing = frame_facts(None, None, None, LAYOUT.bend)
    assert not nothing.predicted and not nothing.measured and nothing.unposed == [] and nothing.rolling is None
    assert all(h.contact_predicted is None and h.contact_measured is None for h in nothing.hands)


def test_the_metrics_are_numbers_or_none_for_n_a():
    metrics = RunningMetrics(LAYOUT.bend)
    empty = pressed((0, 0))
    metrics.add(empty, empty)  # no cell above the threshold in either map: contact IoU 0/0, volumetric 0/0
    facts = frame_facts(empty, None, empty, LAYOUT.bend, metrics=metrics)
    assert facts.rolling["contact_iou"] is None and facts.cumulative["volumetric_iou"] is None
    assert facts.rolling["temporal_accuracy"] == 1.0 and facts.rolling["mae"] == 0.0
    assert [metric_text(v) for v in (None, math.nan, 0.0, 0.12345)] == ["n/a", "n/a", "0.000", "0.123"]


def test_the_video_the_summary_and_the_recording_show_one_record(episode_dir, tmp_path, capsys, monkeypatch):
    """The conftest episode: the right hand has no pose at frames 3, 10, 17, 24, 31, 38 (40 frames)."""
    monkeypatch.delenv("DISPLAY", raising=False)
    video, rrd = tmp_path / "r.mp4", tmp_path / "r.rrd"
    assert main(["replay", str(episode_dir), "--headless", "--out", str(video), "--rerun", str(rrd)]) == 0
    printed = capsys.readouterr().out
    lamps = next(line for line in printed.splitlines() if line.startswith("contact   lamps"))
    assert "(left " in lamps and " of 40 frames, right " in lamps and " of 34; " in lamps  # the unposed frames uncounted

    rows, _ = recording_rows(rrd)
    predicted = rows["/contact/predicted"]
    assert math.isnan(predicted.at("Scalars:scalars", 10)[1]) and not math.isnan(predicted.at("Scalars:scalars", 10)[0])
    assert not any(math.isnan(v) for v in predicted.at("Scalars:scalars", 11))
    right_values = np.frombuffer(bytes(rows["/pressure/predicted/right"].at("DepthImage:buffer", 10)[0]), np.float16)
    assert np.isnan(right_values).all()  # not a map of zeros

    with VideoReader(video) as reader:
        frame, posed = reader.read(10).astype(int), reader.read(11).astype(int)
    row = max(150 // 3, 14)  # the lamps' row height in the 150-pixel strip
    strip = CAMERA_HEIGHT + PANEL_HEIGHT
    for image, unknown in ((frame, True), (posed, False)):
        x, y = lamp_centre(0, 1, 480, row)  # the right hand's predicted lamp, in the strip's third panel
        colour = image[strip + y, 960 + x]
        assert (np.abs(colour - UNKNOWN).max() < 12) == unknown, colour
    maps = frame[CAMERA_HEIGHT:strip, 480:960]
    right_map = maps[40:40 + 21 * 14, 10 + 21 * 14 + 10:10 + 2 * 21 * 14 + 10]  # panel_cell(480, 360) = 14
    background = np.abs(right_map - BACKGROUND).max(axis=-1) < 12
    assert background.mean() > 0.9, "the unposed right hand is drawn as a map"  # background with "no pose" on it


# --- the record at its edges, by value -----------------------------------------------------------------------------------
def test_hand_contact_judges_each_hand_on_its_own_cells():
    assert hand_contact(pressed((8, 0)), LAYOUT.bend).tolist() == [True, False]
    assert hand_contact(pressed((0, 8)), LAYOUT.bend).tolist() == [False, True]
    assert hand_contact(pressed((7, 151)), LAYOUT.bend).tolist() == [False, True]
    assert hand_contact(pressed((8, 8), 0.3), LAYOUT.bend, threshold=0.3).tolist() == [False, False]  # strictly above
    assert hand_contact(np.full((2, 21, 21), np.nan), LAYOUT.bend).tolist() == [False, False]


def test_posed_and_measured_come_from_the_values_when_not_given():
    prediction, measurement = pressed((20, 20)), pressed((20, 20))
    prediction[0] = np.nan
    measurement[1] = np.nan
    facts = frame_facts(prediction, None, measurement, LAYOUT.bend)
    left, right = facts.hands
    assert (left.posed, left.measured, left.contact_predicted, left.contact_measured, left.agree) == (
        False, True, None, True, None)
    assert (right.posed, right.measured, right.contact_predicted, right.contact_measured, right.agree) == (
        True, False, True, None, None)
    assert facts.predicted and facts.measured and facts.posed == (False, True) and facts.unposed == ["left"]
    assert np.array_equal(facts.contact("predicted"), [np.nan, 1.0], equal_nan=True)
    assert np.array_equal(facts.contact("measured"), [1.0, np.nan], equal_nan=True)
    assert facts.rolling is None and facts.cumulative is None


def test_agreement_needs_both_contacts_known():
    assert HandFacts(True, True, True, True).agree is True
    assert HandFacts(True, True, False, False).agree is True
    assert HandFacts(True, True, False, True).agree is False
    assert HandFacts(True, False, True, None).agree is None
    assert HandFacts(False, True, None, False).agree is None
    facts = frame_facts(pressed((0, 30)), (True, True), pressed((0, 0)), LAYOUT.bend)
    assert [h.agree for h in facts.hands] == [True, False]
    assert facts.contact("predicted").tolist() == [0.0, 1.0] and facts.contact("measured").tolist() == [0.0, 0.0]


def test_a_measurement_without_a_prediction_and_the_running_metrics():
    metrics = RunningMetrics(LAYOUT.bend)
    metrics.add(pressed((30, 0)), pressed((30, 30)))
    facts = frame_facts(None, None, pressed((30, 30)), LAYOUT.bend, metrics=metrics)
    assert not facts.predicted and facts.measured and facts.unposed == [] and facts.posed == (False, False)
    assert [(h.contact_predicted, h.contact_measured, h.measured) for h in facts.hands] == [(None, True, True),
                                                                                         (None, True, True)]
    assert facts.cumulative["contact_iou"] == pytest.approx(0.5) and facts.rolling["contact_iou"] == pytest.approx(0.5)
    assert facts.cumulative["temporal_accuracy"] == 1.0  # 30 of 302 cells ≥ 5 %: both frames are contact


def test_the_record_is_frozen():
    facts = frame_facts(pressed((8, 8)), None, pressed((8, 8)), LAYOUT.bend)
    with pytest.raises(dataclasses.FrozenInstanceError):
        facts.measured = False
    with pytest.raises(dataclasses.FrozenInstanceError):
        facts.hands[0].contact_predicted = False
    assert isinstance(facts, FrameFacts)
