"""Turn `touchanything eval` results into the findings tables (the paper's Table 2 layout and the
view-dropout ablation).

    .venv/bin/python scripts/findings_table.py data/eval MODEL [ABLATION_MODEL]

reads data/eval/<model>/<split>/results.json for split test_seen and test_unseen and prints Markdown.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

VIEWS = ("ego", "ego+left", "ego+right", "all")
SPLITS = ("test_seen", "test_unseen")
COLUMNS = (("temporal_accuracy", "TA"), ("contact_iou", "C-IoU"), ("volumetric_iou", "V-IoU"), ("mae", "MAE"))


def load(root: Path, model: str, split: str, mode: str = "stitched") -> dict:
    data = json.loads((root / model / split / "results.json").read_text())
    return {r["views"]: r[mode] for r in data["results"]}


def cell(value: float) -> str:
    return "n/a" if value is None or math.isnan(value) else f"{value:.3f}"


def table2(root: Path, model: str, mode: str) -> list[str]:
    results = {split: load(root, model, split, mode) for split in SPLITS}
    header = " | ".join(f"{split.split('_')[1]} {name}" for split in SPLITS for _, name in COLUMNS)
    lines = [f"| scene | views | {header} |", "|---|---|" + "---|" * (2 * len(COLUMNS))]
    scenes = ["overall"] + sorted({s for r in results.values() for v in r.values() for s in v} - {"overall"})
    for scene in scenes:
        for views in VIEWS:
            cells = [cell(results[split].get(views, {}).get(scene, {}).get(key, math.nan)) for split in SPLITS for key, _ in COLUMNS]
            lines.append(f"| {scene} | {views} | " + " | ".join(cells) + " |")
    return lines


def ablation(root: Path, with_dropout: str, without: str) -> list[str]:
    lines = ["| training | split | V-IoU all views | V-IoU ego only | ΔV (all − ego) | C-IoU all | C-IoU ego |",
             "|---|---|---|---|---|---|---|"]
    for label, model in (("with view dropout", with_dropout), ("without view dropout", without)):
        for split in SPLITS:
            r = load(root, model, split)
            v_all, v_ego = r["all"]["overall"]["volumetric_iou"], r["ego"]["overall"]["volumetric_iou"]
            lines.append(f"| {label} | {split} | {cell(v_all)} | {cell(v_ego)} | {cell(v_all - v_ego)} | "
                         f"{cell(r['all']['overall']['contact_iou'])} | {cell(r['ego']['overall']['contact_iou'])} |")
    return lines


def main() -> None:
    root, model = Path(sys.argv[1]), sys.argv[2]
    print("\n".join(table2(root, model, "stitched")))
    print()
    print("\n".join(table2(root, model, "causal")))
    if len(sys.argv) > 3:
        print()
        print("\n".join(ablation(root, model, sys.argv[3])))


if __name__ == "__main__":
    main()
