"""Turn `touchanything eval` results into the findings tables of docs/findings.md: every model beside the
baselines, the two seeds' spread, what vision adds over the pose (the pose-only rows), the views, and the
paper's Table 2 layout for the bundled model, and every model on the held-out trajectories of the
evaluation split and of the seed-13 test episodes, pooled.

    .venv/bin/python scripts/findings_table.py data/runs nano nano_seed7 --others nano_pose_only baseline_pose baseline_frames

reads RUNS/<model>/eval_<split>/results.json and, for the pooled table, RUNS/<model>/eval13_<split>/results.json
(both written by scripts/train_bundled_models.sh) for the splits test_seen and test_unseen and prints Markdown.
The first model is the bundled one, the second its other seed.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

VIEWS = ("ego", "ego+left", "ego+right", "all")
SPLITS = ("test_seen", "test_unseen")
COLUMNS = (("volumetric_iou", "V-IoU"), ("contact_iou", "C-IoU"), ("temporal_accuracy", "TA"), ("mae", "MAE"))
POSE_ONLY = " (pose only)"


def load(root: Path, model: str, split: str, mode: str) -> dict:
    """{views or "views (pose only)": {scene: {metric: value}}} of one results.json ({} when absent)."""
    path = root / model / f"eval_{split}" / "results.json"
    if not path.is_file():
        return {}
    data = json.loads(path.read_text())
    return {r["views"] + (POSE_ONLY if r.get("pose_only") else ""): r[mode] for r in data["results"] if not r.get("baseline")}


def cell(value: float | None) -> str:
    return "n/a" if value is None or math.isnan(value) else f"{value:.3f}"


def overall(results: dict, views: str, key: str) -> float:
    return results.get(views, {}).get("overall", {}).get(key, math.nan)


def trajectories(root: Path, model: str, folder: str) -> list[dict]:
    """The per-trajectory causal metrics of the all-views result in RUNS/<model>/<folder>/results.json ([] when absent)."""
    path = root / model / folder / "results.json"
    if not path.is_file():
        return []
    results = json.loads(path.read_text())["results"]
    return next((r["trajectories"] for r in results if r["views"] == "all" and not r.get("pose_only") and not r.get("baseline")), [])


def trajectory_mean(rows: list[dict], key: str) -> float:
    """The official protocol's average: the mean over trajectories of a per-trajectory metric, NaN ones left out."""
    values = [r["causal"][key] for r in rows if r["causal"].get(key) is not None and not math.isnan(r["causal"][key])]
    return sum(values) / len(values) if values else math.nan


def pooled_table(root: Path, models: list[str]) -> list[str]:
    """V-IoU / C-IoU, all views, causal: the evaluation split (eval_), the seed-13 test episodes (eval13_) and
    their trajectories pooled (the mean over all of them, not the mean of the two means)."""
    lines = ["| model | " + " | ".join(f"{split.split('_')[1]} {part}" for split in SPLITS
                                      for part in ("eval split", "seed 13", "pooled")) + " |", "|---|" + "---|" * 6]
    for model in models:
        cells = []
        for split in SPLITS:
            parts = [trajectories(root, model, f"eval_{split}"), trajectories(root, model, f"eval13_{split}")]
            for rows in (*parts, parts[0] + parts[1] if all(parts) else []):
                cells.append(f"{cell(trajectory_mean(rows, 'volumetric_iou'))} / {cell(trajectory_mean(rows, 'contact_iou'))} "
                             f"({len(rows)})")
        lines.append(f"| {model} | " + " | ".join(cells) + " |")
    return lines


def models_table(root: Path, models: list[str], mode: str) -> list[str]:
    """All views, overall: every model and baseline on both test splits."""
    header = " | ".join(f"{split.split('_')[1]} {name}" for split in SPLITS for _, name in COLUMNS)
    lines = [f"| model | {header} |", "|---|" + "---|" * (2 * len(COLUMNS))]
    for model in models:
        results = {split: load(root, model, split, mode) for split in SPLITS}
        lines.append(f"| {model} | " + " | ".join(cell(overall(results[s], "all", k)) for s in SPLITS for k, _ in COLUMNS) + " |")
    return lines


def vision_table(root: Path, models: list[str], mode: str) -> list[str]:
    """Frames + pose against the pose-only rows (nano_pose_only on black frames), all views, overall."""
    lines = ["| model | split | V-IoU frames + pose | V-IoU pose only | Δ V-IoU | C-IoU frames + pose | C-IoU pose only | "
             "Δ C-IoU |", "|---|---|---|---|---|---|---|---|"]
    for model in models:
        for split in SPLITS:
            r = load(root, model, split, mode)
            v, vb = overall(r, "all", "volumetric_iou"), overall(r, "all" + POSE_ONLY, "volumetric_iou")
            c, cb = overall(r, "all", "contact_iou"), overall(r, "all" + POSE_ONLY, "contact_iou")
            lines.append(f"| {model} | {split} | {cell(v)} | {cell(vb)} | {cell(v - vb)} | {cell(c)} | {cell(cb)} | {cell(c - cb)} |")
    return lines


def views_table(root: Path, models: list[str], mode: str) -> list[str]:
    """V-IoU / C-IoU per view set, overall."""
    lines = ["| model | split | " + " | ".join(VIEWS) + " | all − ego |", "|---|---|" + "---|" * (len(VIEWS) + 1)]
    for model in models:
        for split in SPLITS:
            r = load(root, model, split, mode)
            cells = [f"{cell(overall(r, v, 'volumetric_iou'))} / {cell(overall(r, v, 'contact_iou'))}" for v in VIEWS]
            gain = (f"{cell(overall(r, 'all', 'volumetric_iou') - overall(r, 'ego', 'volumetric_iou'))} / "
                    f"{cell(overall(r, 'all', 'contact_iou') - overall(r, 'ego', 'contact_iou'))}")
            lines.append(f"| {model} | {split} | " + " | ".join(cells) + f" | {gain} |")
    return lines


def table2(root: Path, model: str, mode: str) -> list[str]:
    """The paper's Table 2 layout: scene × views, both splits."""
    results = {split: load(root, model, split, mode) for split in SPLITS}
    header = " | ".join(f"{split.split('_')[1]} {name}" for split in SPLITS for _, name in COLUMNS)
    lines = [f"| scene | views | {header} |", "|---|---|" + "---|" * (2 * len(COLUMNS))]
    scenes = ["overall"] + sorted({s for r in results.values() for v in r.values() for s in v} - {"overall"})
    for scene in scenes:
        for views in (v + suffix for v in VIEWS for suffix in ("", POSE_ONLY)):
            if any(views in results[split] for split in SPLITS):
                cells = [cell(results[s].get(views, {}).get(scene, {}).get(k, math.nan)) for s in SPLITS for k, _ in COLUMNS]
                lines.append(f"| {scene} | {views} | " + " | ".join(cells) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path)
    parser.add_argument("model")
    parser.add_argument("second_seed")
    parser.add_argument("--others", nargs="*", default=[], help="baselines and other models for the first table")
    args = parser.parse_args()
    seeds = [args.model, args.second_seed]
    sections = [("Held-out trajectories pooled: V-IoU / C-IoU (trajectories), all views, causal",
                 pooled_table(args.runs, seeds + args.others)),
                ("Models and baselines (all views, overall, causal)", models_table(args.runs, seeds + args.others, "causal")),
                ("Models and baselines (all views, overall, official stitched)", models_table(args.runs, seeds + args.others, "stitched")),
                ("What vision adds over the pose (all views, causal)", vision_table(args.runs, seeds, "causal")),
                ("Views: V-IoU / C-IoU (causal)", views_table(args.runs, seeds, "causal")),
                (f"Table 2 layout for {args.model}, causal newest frame", table2(args.runs, args.model, "causal")),
                (f"Table 2 layout for {args.model}, official stitched", table2(args.runs, args.model, "stitched"))]
    for title, lines in sections:
        print(f"### {title}\n")
        print("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
