"""The evaluation report from the library (`evaluation_report`): a user of `evaluate` makes the same results.json
and Markdown tables as `touchanything eval`, without the command."""
from __future__ import annotations

import json
import math

from touchanything.inference.evaluation.evaluation import EvaluationResult, vision_share_summary
from touchanything.inference.evaluation.evaluation_report import (
    RESULT_FILES,
    baseline_pairs,
    markdown,
    result_record,
    results_json,
    results_payload,
)
from touchanything.inference.evaluation.metrics import ALL_METRICS


def metrics(mae: float, iou: float) -> dict[str, float]:
    return dict.fromkeys(ALL_METRICS, 0.0) | {"mae": mae, "contact_iou": iou}


ROWS = [{"path": "a.h5", "scene": "office", "task": "cup", "frames": 30, "stitched": metrics(0.1, 0.5),
         "causal": metrics(0.3, math.nan)},
        {"path": "b.h5", "scene": "home", "task": "mug", "frames": 20, "stitched": metrics(0.2, 0.6),
         "causal": metrics(0.5, 0.2)}]
BLANK_ROWS = [dict(r, stitched=metrics(0.4, 0.25)) for r in ROWS]


def results() -> list[EvaluationResult]:
    return [EvaluationResult("all", ROWS), EvaluationResult("all", BLANK_ROWS, blank=True),
            EvaluationResult("all", ROWS, baseline="pose_mlp", failures=["c.h5: unreadable"])]


def test_the_pose_only_twin_pairs_with_its_real_result_and_a_baseline_does_not():
    real, blank, _ = got = results()
    assert baseline_pairs(got) == [(real, blank)]
    assert "vision_share" not in result_record(real, got)
    assert result_record(blank, got)["vision_share"]["stitched"] == vision_share_summary(real, blank, "stitched")


def test_results_json_holds_the_settings_and_a_record_per_result():
    got = results()
    text = results_json(got, "test_seen", "best_model.pth", "frames", "pose.pth", {"pose_mlp": "models/pose_mlp.pth"})
    assert RESULT_FILES == ("results.json", "results.md") and text.endswith("}\n")
    payload = json.loads(text)
    assert payload == json.loads(json.dumps(results_payload(got, "test_seen", "best_model.pth", "frames", "pose.pth",
                                                            {"pose_mlp": "models/pose_mlp.pth"})))
    assert {k: payload[k] for k in ("split", "checkpoint", "ego_path", "pose_only_checkpoint", "baselines")} == {
        "split": "test_seen", "checkpoint": "best_model.pth", "ego_path": "frames", "pose_only_checkpoint": "pose.pth",
        "baselines": {"pose_mlp": "models/pose_mlp.pth"}}
    assert [(r["views"], r["pose_only"], r["baseline"]) for r in payload["results"]] == [
        ("all", False, None), ("all", True, None), ("all", False, "pose_mlp")]
    assert payload["results"][2]["failed"] == ["c.h5: unreadable"] and payload["results"][0]["trajectories"][0]["path"] == "a.h5"
    assert math.isnan(payload["results"][0]["causal"]["home"]["contact_iou"]) is False
    assert math.isnan(payload["results"][0]["causal"]["office"]["contact_iou"])  # NaN written, read back


def test_the_markdown_report_has_a_row_per_result_and_scene_and_the_vision_share():
    table = markdown(results(), "test_seen", "pose.pth", {"pose_mlp": "models/pose_mlp.pth"})
    lines = table.splitlines()
    assert lines[0] == "# Evaluation on `test_seen`"
    assert "Pose-only rows: `pose.pth` with every frame black." in lines
    assert "Baseline rows `· pose_mlp`: `models/pose_mlp.pth`." in lines
    assert "## official stitched (average of covering clips)" in lines and "## causal newest-frame" in lines
    assert sum(line.startswith("| all (pose only) | office |") for line in lines) == 4  # 2 metric tables × 2 modes
    assert sum(line.startswith("| all · pose_mlp | home |") for line in lines) == 4
    assert sum(line.startswith("### ") and "share carried by vision" in line for line in lines) == 2
    assert "| n/a |" in table  # the causal contact IoU of the office trajectory: no data


def test_without_pose_only_or_baselines_the_report_has_no_share_tables():
    table = markdown(results()[:1], "val")
    assert "Pose-only rows" not in table and "Baseline rows" not in table and "share carried by vision" not in table
    payload = json.loads(results_json(results()[:1], "val", "best_model.pth"))
    assert payload["pose_only_checkpoint"] is None and payload["baselines"] == {} and payload["ego_path"] == "frames"
