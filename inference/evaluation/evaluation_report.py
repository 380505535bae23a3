"""The report of an evaluation (`evaluation.evaluate`): the results.json records and the Markdown tables.

`markdown` lays the results out as the paper's Table 2 (a row per view configuration and scene), `results_json`
is the text of results.json; `touchanything eval` writes both, and a library user of `evaluate` can make the
same report from its `EvaluationResult`s.
"""
from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

from touchanything.inference.evaluation.metrics import DETECTION_METRICS, EVENT_METRICS, METRICS

if TYPE_CHECKING:  # evaluation imports torch: the command line's --help loads this module
    from touchanything.inference.evaluation.evaluation import EvaluationResult

RESULT_FILES = ("results.json", "results.md")
TIMING_COLUMNS = DETECTION_METRICS[:3] + EVENT_METRICS[:4]
"""The extra metrics in the Markdown table (support and event counts are in results.json only)."""
MODES = ("stitched", "causal")


def _cell(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:.4f}"


def _rows(label: str, summary: dict[str, dict[str, float]], keys: tuple[str, ...]) -> list[str]:
    return [f"| {label} | {scene} | " + " | ".join(_cell(metrics[k]) for k in keys) + " |" for scene, metrics in summary.items()]


def _shares(real: EvaluationResult, blank: EvaluationResult, mode: str) -> dict[str, dict[str, float]]:
    """`evaluation.vision_share_summary`, imported where used (it loads torch)."""
    from touchanything.inference.evaluation.evaluation import vision_share_summary

    return vision_share_summary(real, blank, mode)


def _table(results: list[EvaluationResult], mode: str, keys: tuple[str, ...]) -> list[str]:
    """A row per view configuration (and its pose-only baseline) and scene, a column per metric of `keys`."""
    lines = ["| views | scene | " + " | ".join(keys) + " |", "|---|---|" + "---|" * len(keys)]
    for result in results:
        lines += _rows(result.label, result.summary(mode), keys)
    return lines + [""]


def baseline_pairs(results: list[EvaluationResult]) -> list[tuple[EvaluationResult, EvaluationResult]]:
    """(real, pose-only twin) results of the model for the same view configuration."""
    model = [r for r in results if not r.baseline]
    real = {r.views: r for r in model if not r.blank}
    return [(real[r.views], r) for r in model if r.blank]


def _share_table(results: list[EvaluationResult], mode: str) -> list[str]:
    """The vision share of each metric, a row per view configuration and scene (none without baselines)."""
    pairs = baseline_pairs(results)
    if not pairs:
        return []
    keys = METRICS + TIMING_COLUMNS
    lines = [f"### {mode}: share carried by vision (real − pose only) / max(real, pose only); MAE reversed", "",
             "| views | scene | " + " | ".join(keys) + " |", "|---|---|" + "---|" * len(keys)]
    for real, blank in pairs:
        lines += _rows(real.views, _shares(real, blank, mode), keys)
    return lines + [""]


def markdown(results: list[EvaluationResult], split: str, pose_only: str | None = None,
             baselines: dict[str, str] | None = None) -> str:
    """The paper's Table 2 layout (a row per view configuration and scene), stitched and causal, each followed
    by the contact-timing metrics the official module computes but does not report, and by the vision share
    when pose-only baselines (of the checkpoint `pose_only`) were run; rows "views · NAME" are the baseline
    checkpoints `baselines` (name → checkpoint)."""
    lines = [f"# Evaluation on `{split}`", ""]
    if pose_only:
        lines += [f"Pose-only rows: `{pose_only}` with every frame black.", ""]
    for name, checkpoint in (baselines or {}).items():
        lines += [f"Baseline rows `· {name}`: `{checkpoint}`.", ""]
    for mode, title in (("stitched", "official stitched (average of covering clips)"), ("causal", "causal newest-frame")):
        lines += [f"## {title}", ""] + _table(results, mode, METRICS)
        lines += [f"### {mode}: contact timing (computed officially, not reported)", ""] + _table(results, mode, TIMING_COLUMNS)
        lines += _share_table(results, mode)
    return "\n".join(lines)


def result_record(result: EvaluationResult, results: list[EvaluationResult]) -> dict:
    """One entry of results.json; a pose-only baseline also carries its `vision_share` per mode and scene."""
    record = {"views": result.views, "pose_only": result.blank, "baseline": result.baseline or None,
              "stitched": result.summary("stitched"),
              "causal": result.summary("causal")}
    real = next((r for r, b in baseline_pairs(results) if b is result), None)
    if real is not None:
        record["vision_share"] = {mode: _shares(real, result, mode) for mode in MODES}
    return {**record, "trajectories": result.rows, "failed": result.failures}


def results_payload(results: list[EvaluationResult], split: str, checkpoint: str, ego_path: str = "frames",
                    pose_only: str | None = None, baselines: dict[str, str] | None = None) -> dict:
    """The content of results.json: the run's settings (`checkpoint` evaluated on `split`, `pose_only` the
    checkpoint of the pose-only rows, `baselines` name → checkpoint) and a `result_record` per result."""
    return {"split": split, "checkpoint": checkpoint, "ego_path": ego_path, "pose_only_checkpoint": pose_only,
            "baselines": dict(baselines or {}), "results": [result_record(r, results) for r in results]}


def results_json(results: list[EvaluationResult], split: str, checkpoint: str, ego_path: str = "frames",
                 pose_only: str | None = None, baselines: dict[str, str] | None = None) -> str:
    """The text of results.json (`results_payload`; NaN for metrics without data)."""
    payload = results_payload(results, split, checkpoint, ego_path, pose_only, baselines)
    return json.dumps(payload, indent=1, allow_nan=True) + "\n"
