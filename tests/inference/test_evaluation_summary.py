"""The evaluation result's summary by value: the nanmean over trajectories overall and per scene, the label of a run,
the metrics of a trajectory over its predicted frames only, and the vision share per scene; and the figures
results.json and results.md call "overall" and per scene, worked out by hand from small synthetic trajectories
(not from the code under test): the official mean over trajectories — nanmean per metric, the ground-truth counts
included — of per-trajectory metrics."""
from __future__ import annotations

import math

import numpy as np
import pytest

from touchanything.core.tactile_layout import TactileLayout
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


# --- the headline figures worked out by hand -----------------------------------------------------------------------------
LAYOUT = TactileLayout.default()
BEND = LAYOUT.bend


def full(value: float) -> np.ndarray:
    """(2, 21, 21): `value` on every cell of the layout (217 per hand), NaN outside."""
    return np.where(LAYOUT.valid, value, np.nan)


NOTHING = np.full((2, 21, 21), np.nan)

TRAJECTORIES = {
    # name: (scene, predicted frames, measured frames). Every frame is uniform over the layout's cells, so each
    # ratio below is the same with any cell count.
    "a": ("Home", [full(0.2)], [full(0.4)]),
    # V-IoU 0.2/0.4 = 1/2; C-IoU 1 (every cell above 0.1 in both); MAE 0.2; both frames "contact": TA 1, TP 1 →
    # precision = recall = F1 = 1, support 1; one kept frame: the event ratios NaN, counts 0.
    "b": ("Home", [full(0.3)] * 3 + [NOTHING], [full(0.9)] * 4),
    # the last frame has no prediction: left out. V-IoU 0.9/2.7 → 1/3; C-IoU 1; MAE 0.6; TA 1, support 3, F1 1;
    # flags T,T,T: no onset or offset in either: the event ratios 0/0 → 0.0, counts 0.
    "c": ("Office", [full(0.05), full(0.0)], [full(0.05), full(0.5)]),
    # V-IoU (0.05 + 0) / (0.05 + 0.5) = 1/11; C-IoU: 0.05 is below 0.1, the second frame only measured → 0/n = 0;
    # MAE (0 + 0.5) / 2 = 0.25; flags predicted F,F measured F,T: TA 1/2, support 1, TP 0 → precision, recall,
    # F1 0; one measured onset (at 1), none predicted: onset precision 0/0 → 0.0, recall 0/1 = 0.0, 1 onset.
    "d": ("Office", [full(0.0)] * 2, [full(0.0)] * 2),
    # nothing pressed: V-IoU 0/0 and C-IoU 0/0 are NaN; MAE 0; TA 1; no contact: precision, recall, F1 0.0,
    # support 0; event ratios 0.0, counts 0.
    "e": ("Office", [full(0.5)], [NOTHING]),
    # no measured cell: every reported metric NaN, precision / recall / F1 NaN; the counts 0 (not NaN).
}

PER_TRAJECTORY = {  # name: (V-IoU, C-IoU, MAE, TA, F1, support, measured onsets), by hand from the comments above
    "a": (1 / 2, 1.0, 0.2, 1.0, 1.0, 1, 0),
    "b": (1 / 3, 1.0, 0.6, 1.0, 1.0, 3, 0),
    "c": (1 / 11, 0.0, 0.25, 0.5, 0.0, 1, 1),
    "d": (math.nan, math.nan, 0.0, 1.0, 0.0, 0, 0),
    "e": (math.nan, math.nan, math.nan, math.nan, math.nan, 0, 0),
}
KEYS = ("volumetric_iou", "contact_iou", "mae", "temporal_accuracy", "temporal_f1", "temporal_support", "num_gt_onsets")

EXPECTED = {  # the mean over the trajectories where a value is defined, worked out by hand
    "overall": {"volumetric_iou": (1 / 2 + 1 / 3 + 1 / 11) / 3,  # = 61/198: d and e are NaN
                "contact_iou": 2 / 3, "mae": (0.2 + 0.6 + 0.25 + 0.0) / 4, "temporal_accuracy": 3.5 / 4,
                "temporal_f1": 2 / 4, "temporal_support": 5 / 5, "num_gt_onsets": 1 / 5},
    "Home": {"volumetric_iou": 5 / 12, "contact_iou": 1.0, "mae": 0.4, "temporal_accuracy": 1.0, "temporal_f1": 1.0,
             "temporal_support": 2.0, "num_gt_onsets": 0.0},
    "Office": {"volumetric_iou": 1 / 11, "contact_iou": 0.0, "mae": 0.125, "temporal_accuracy": 0.75, "temporal_f1": 0.0,
               "temporal_support": 1 / 3, "num_gt_onsets": 1 / 3},
}
"""A pooled ratio would differ: e.g. V-IoU Σmin / Σmax over all frames = 1.15/3.65 = 0.315 (not 0.308), C-IoU 4n/5n =
0.8 (not 2/3); a frame-weighted mean of MAE 0.39 (not 0.2625); a plain mean is NaN."""


@pytest.fixture(scope="module")
def result() -> EvaluationResult:
    rows = []
    for name, (scene, predicted, measured) in TRAJECTORIES.items():
        predicted, measured = np.stack(predicted), np.stack(measured)
        rows.append({"path": name, "scene": scene, "task": name, "frames": len(measured),
                     "stitched": trajectory_metrics(predicted, measured, BEND),
                     "causal": trajectory_metrics(measured, measured, BEND)})  # a perfect prediction
    return EvaluationResult("all", rows)


def test_each_trajectorys_metrics_are_the_hand_worked_values(result):
    for row in result.rows:
        got = row["stitched"]
        for key, want in zip(KEYS, PER_TRAJECTORY[row["path"]]):
            assert got[key] == pytest.approx(want, abs=1e-12, nan_ok=True), (row["path"], key)
    c = next(r["stitched"] for r in result.rows if r["path"] == "c")
    assert (c["onset_precision"], c["onset_recall"], c["num_gt_offsets"]) == (0.0, 0.0, 0)
    assert c["mae_left"] == c["mae_right"] == pytest.approx(0.25, abs=1e-12)


def test_overall_and_per_scene_are_nanmeans_over_trajectories(result):
    summary = result.summary("stitched")
    assert list(summary) == ["overall", "Home", "Office"]
    for scene, expected in EXPECTED.items():
        for key, want in expected.items():
            assert summary[scene][key] == pytest.approx(want, abs=1e-12), (scene, key)
    assert summary["overall"]["volumetric_iou"] == pytest.approx(61 / 198, abs=1e-12)
    assert summary["Home"]["onset_precision"] == 0.0  # a: NaN (one kept frame) is left out; b: 0/0 → 0.0
    causal = result.summary("causal")  # the measured maps as the prediction
    assert causal["overall"]["mae"] == 0.0 and causal["overall"]["volumetric_iou"] == 1.0
    assert causal["Office"]["temporal_accuracy"] == 1.0 and causal["Office"]["contact_iou"] == 1.0


def test_a_trajectory_with_every_metric_undefined_does_not_move_the_means(result):
    without = EvaluationResult("all", [r for r in result.rows if r["path"] != "e"]).summary("stitched")
    full_summary = result.summary("stitched")
    for key in ("volumetric_iou", "contact_iou", "mae", "temporal_accuracy", "temporal_f1"):
        assert without["overall"][key] == pytest.approx(full_summary["overall"][key], abs=1e-12), key
    assert without["overall"]["temporal_support"] == pytest.approx(5 / 4)  # a count: e's 0 is a value, not NaN
