"""Turn `touchanything eval` results into the findings tables of docs/findings.md: the paper's Table 2 layout
with the pose-only rows, what vision adds over the pose, the spread between two training seeds, and the
view-dropout ablation.

    .venv/bin/python scripts/findings_table.py data/eval MODEL SECOND_SEED NO_DROPOUT [OTHER_MODEL ...]

reads data/eval/<model>/<split>/results.json (written by `eval --pose-only-baseline …`) for the splits
test_seen and test_unseen and prints Markdown.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

VIEWS = ("ego", "ego+left", "ego+right", "all")
SPLITS = ("test_seen", "test_unseen")
COLUMNS = (("temporal_accuracy", "TA"), ("contact_iou", "C-IoU"), ("volumetric_iou", "V-IoU"), ("mae", "MAE"))
POSE_ONLY = " (pose only)"


def load(root: Path, model: str, split: str, mode: str = "stitched") -> dict:
    """{views or "views (pose only)": {scene: {metric: value}}} of one results.json."""
    data = json.loads((root / model / split / "results.json").read_text())
    return {r["views"] + (POSE_ONLY if r.get("pose_only") else ""): r[mode] for r in data["results"]}


def cell(value: float | None) -> str:
    return "n/a" if value is None or math.isnan(value) else f"{value:.3f}"


def overall(results: dict, views: str, key: str) -> float:
    return results.get(views, {}).get("overall", {}).get(key, math.nan)


def table2(root: Path, model: str, mode: str) -> list[str]:
    results = {split: load(root, model, split, mode) for split in SPLITS}
    header = " | ".join(f"{split.split('_')[1]} {name}" for split in SPLITS for _, name in COLUMNS)
    lines = [f"| scene | views | {header} |", "|---|---|" + "---|" * (2 * len(COLUMNS))]
    scenes = ["overall"] + sorted({s for r in results.values() for v in r.values() for s in v} - {"overall"})
    for scene in scenes:
        for views in (v + suffix for v in VIEWS for suffix in ("", POSE_ONLY)):
            if not any(views in results[split] for split in SPLITS):
                continue
            cells = [cell(results[split].get(views, {}).get(scene, {}).get(key, math.nan)) for split in SPLITS for key, _ in COLUMNS]
            lines.append(f"| {scene} | {views} | " + " | ".join(cells) + " |")
    return lines


def vision_table(root: Path, models: list[str]) -> list[str]:
    """Frames + pose against the pose-only rows, all views, overall, official stitched."""
    lines = ["| model | split | C-IoU frames + pose | C-IoU pose only | Δ C-IoU | V-IoU frames + pose | V-IoU pose only | "
             "Δ V-IoU | TA frames + pose | TA pose only |", "|---|---|---|---|---|---|---|---|---|---|"]
    for model in models:
        for split in SPLITS:
            r = load(root, model, split)
            c, cb = overall(r, "all", "contact_iou"), overall(r, "all" + POSE_ONLY, "contact_iou")
            v, vb = overall(r, "all", "volumetric_iou"), overall(r, "all" + POSE_ONLY, "volumetric_iou")
            t, tb = overall(r, "all", "temporal_accuracy"), overall(r, "all" + POSE_ONLY, "temporal_accuracy")
            lines.append(f"| {model} | {split} | {cell(c)} | {cell(cb)} | {cell(c - cb)} | {cell(v)} | {cell(vb)} | "
                         f"{cell(v - vb)} | {cell(t)} | {cell(tb)} |")
    return lines


def views_table(root: Path, models: list[str], label: dict[str, str]) -> list[str]:
    """All views against ego only per model (the seeds' spread, the dropout ablation)."""
    lines = ["| training | split | V-IoU all views | V-IoU ego only | ΔV (all − ego) | C-IoU all | C-IoU ego | "
             "ΔC (all − ego) |", "|---|---|---|---|---|---|---|---|"]
    for model in models:
        for split in SPLITS:
            r = load(root, model, split)
            v_all, v_ego = overall(r, "all", "volumetric_iou"), overall(r, "ego", "volumetric_iou")
            c_all, c_ego = overall(r, "all", "contact_iou"), overall(r, "ego", "contact_iou")
            lines.append(f"| {label.get(model, model)} | {split} | {cell(v_all)} | {cell(v_ego)} | {cell(v_all - v_ego)} | "
                         f"{cell(c_all)} | {cell(c_ego)} | {cell(c_all - c_ego)} |")
    return lines


def main() -> None:
    root, model, seed, no_dropout, *others = Path(sys.argv[1]), *sys.argv[2:]
    sections = [("Table 2 layout, official stitched", table2(root, model, "stitched")),
                ("Table 2 layout, causal newest frame", table2(root, model, "causal")),
                ("What vision adds over the pose (all views, stitched)", vision_table(root, [model, seed, no_dropout, *others])),
                ("Views and seeds", views_table(root, [model, seed, no_dropout, *others],
                                                {model: f"{model} (view dropout)", seed: f"{seed} (view dropout)",
                                                 no_dropout: f"{no_dropout} (no view dropout)"}))]
    for title, lines in sections:
        print(f"### {title}\n")
        print("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
