"""The frame-facts record at its edges, by value: the per-hand contact rule on its own, which hand counts as posed
or measured from its values, the NaN of an unknown contact, and that the one record every view reads cannot be
changed by one of them (frozen)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from test_frame_facts import LAYOUT, pressed
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.frame_facts import FrameFacts, HandFacts, frame_facts, hand_contact


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
