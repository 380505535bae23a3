"""The evaluation result's summary by value (found by mutation testing, docs/testing.md): the nanmean over
trajectories overall and per scene, the label of a run, the metrics of a trajectory over its predicted frames
only, and the vision share per scene."""
from __future__ import annotations

import math

import numpy as np
import pytest

from touchanything.inference.evaluation.evaluation import EvaluationResult, trajectory_metrics, vision_share_summary
from touchanything.inference.evaluation.metrics import ALL_METRICS, compute_tactile_metrics


def metrics(mae: float, iou: float) -> dict[str, float]:
    return dict.fromkeys(ALL_METRICS, 0.0) | {"mae": mae, "contact_iou": iou}


ROWS = [{"scene": "office", "stitched": metrics(0.1, 0.5), "causal": metrics(0.3, math.nan)},
        {"scene": "home", "stitched": metrics(0.2, math.nan), "causal": metrics(0.5, 0.2)},
        {"scene": "office", "stitched": metrics(0.6, 0.7), "causal": metrics(0.1, 0.4)}]


def test_the_summary_is_the_nanmean_overall_and_per_scene_for_the_mode_asked():
    stitched = EvaluationResult("all", ROWS).summary("stitched")
    assert list(stitched) == ["overall", "home", "office"]
    assert stitched["overall"]["mae"] == pytest.approx(0.3) and stitched["overall"]["contact_iou"] == pytest.approx(0.6)
    assert stitched["office"]["mae"] == pytest.approx(0.35) and stitched["office"]["contact_iou"] == pytest.approx(0.6)
    assert stitched["home"]["mae"] == pytest.approx(0.2) and math.isnan(stitched["home"]["contact_iou"])
    causal = EvaluationResult("all", ROWS).summary("causal")
    assert causal["overall"]["mae"] == pytest.approx(0.3) and causal["office"]["contact_iou"] == pytest.approx(0.4)
    assert set(causal["home"]) == set(ALL_METRICS)


def test_the_label_names_the_views_the_pose_only_twin_and_a_baseline():
    assert EvaluationResult("ego", []).label == "ego"
    assert EvaluationResult("ego", [], blank=True).label == "ego (pose only)"
    assert EvaluationResult("all", [], baseline="pose MLP").label == "all · pose MLP"
    assert EvaluationResult("all", [], blank=True, baseline="cnn").label == "all · cnn"


def test_vision_share_per_scene_against_the_pose_only_twin():
    blank_rows = [dict(r, stitched=metrics(0.4, 0.25)) for r in ROWS]
    shares = vision_share_summary(EvaluationResult("all", ROWS), EvaluationResult("all", blank_rows, blank=True), "stitched")
    assert list(shares) == ["overall", "home", "office"]
    assert shares["overall"]["mae"] == pytest.approx((0.4 - 0.3) / 0.4)  # an error: lower is better
    assert shares["office"]["contact_iou"] == pytest.approx((0.6 - 0.25) / 0.6)
    assert math.isnan(shares["home"]["contact_iou"])


def test_trajectory_metrics_count_only_the_frames_that_have_a_prediction():
    rng = np.random.default_rng(0)
    gt = rng.uniform(0, 1, (6, 2, 21, 21))
    prediction = rng.uniform(0, 1, (6, 2, 21, 21))
    bend = np.zeros((2, 21, 21), bool)
    prediction[:2] = np.nan  # frames 0 and 1: no prediction (before the first clip)
    got = trajectory_metrics(prediction, gt, bend)
    want = compute_tactile_metrics(prediction[2:], gt[2:], bend)
    assert got.keys() == want.keys()
    assert all(got[k] == want[k] for k in got) and not math.isnan(got["mae"])
    none = trajectory_metrics(np.full((3, 2, 21, 21), np.nan), gt[:3], bend)
    assert math.isnan(none["mae"]) and none["temporal_support"] == 0
