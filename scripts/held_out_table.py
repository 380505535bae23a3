"""The models on the held-out set (data/heldout, scripts/make_datasets.sh) as docs/findings.md shows them: volumetric
and contact IoU (all views, causal, the official per-trajectory mean) per split and over both, each with its 95 %
bootstrap interval, and each model's paired difference against a reference model on the same trajectories.

    .venv/bin/python scripts/held_out_table.py data/runs bundled_nano pico pico_more --against bundled_nano [--set fresh]

reads RUNS/<model>/<set>_<split>/results.json (`touchanything eval --data data/<set> --split SPLIT --views all`,
as scripts/train_bundled_models.sh and scripts/train_frontier.sh write them; set `heldout`, the default, or `fresh`,
the second fresh seed) for the splits test_seen and test_unseen and prints Markdown. The
intervals are those of `touchanything bench` (`inference/evaluation/bootstrap.py`: trajectories drawn within their
split, 2000 draws).
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from touchanything.inference.evaluation.bootstrap import Resampler

SPLITS = ("test_seen", "test_unseen")
METRICS = (("volumetric_iou", "V-IoU"), ("contact_iou", "C-IoU"))


def per_trajectory(runs: Path, model: str, held_out: str) -> dict[str, dict[str, float]]:
    """{trajectory path: {metric: causal value}} over both splits of the `held_out` set, with the split under "split"."""
    out = {}
    for split in SPLITS:
        results = json.loads((runs / model / f"{held_out}_{split}" / "results.json").read_text())["results"]
        rows = next(r for r in results if r["views"] == "all" and not r.get("pose_only") and not r.get("baseline"))
        for row in rows["trajectories"]:
            out[row["path"]] = {**{m: float(row["causal"][m]) for m, _ in METRICS}, "split": split}
    return out


def interval(value: tuple[float, float, float], signed: bool = False) -> str:
    mean, low, high = value
    if any(math.isnan(v) for v in value):
        return "n/a"
    form = "+.3f" if signed else ".3f"
    return f"{mean:{form}} [{low:{form}}, {high:{form}}]"


def table(runs: Path, models: list[str], against: str | None, held_out: str = "heldout") -> list[str]:
    data = {m: per_trajectory(runs, m, held_out) for m in models + ([against] if against and against not in models else [])}
    paths = sorted(data[models[0]])
    for model, values in data.items():
        if sorted(values) != paths:
            raise SystemExit(f"held_out_table.py: {model} and {models[0]} were evaluated on different trajectories "
                             f"of {held_out}: the paired differences need the same ones")
    splits = [data[models[0]][p]["split"] for p in paths]
    groups = {split: [i for i, s in enumerate(splits) if s == split] for split in SPLITS}
    groups["both"] = list(range(len(paths)))
    header = " | ".join(f"{g.replace('test_', '')} ({len(groups[g])}) {name}" for g in groups for _, name in METRICS)
    lines = [f"| model | {header} |", "|---|" + "---|" * (len(groups) * len(METRICS))]
    for model in models:
        cells = []
        for members in groups.values():
            resampler = Resampler([splits[i] for i in members])
            for metric, _ in METRICS:
                values = [data[model][paths[i]][metric] for i in members]
                cells.append(interval(resampler.interval(values)))
        lines.append(f"| {model} | " + " | ".join(cells) + " |")
    if against:
        lines += ["", f"Paired differences against {against} (same trajectories):", "",
                  f"| model | {header} |", "|---|" + "---|" * (len(groups) * len(METRICS))]
        for model in (m for m in models if m != against):
            cells = []
            for members in groups.values():
                resampler = Resampler([splits[i] for i in members])
                for metric, _ in METRICS:
                    a = [data[model][paths[i]][metric] for i in members]
                    b = [data[against][paths[i]][metric] for i in members]
                    cells.append(interval(resampler.difference(a, b), signed=True))
            lines.append(f"| {model} − {against} | " + " | ".join(cells) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path)
    parser.add_argument("models", nargs="+")
    parser.add_argument("--against", help="the reference model of the paired differences")
    parser.add_argument("--set", default="heldout", choices=("heldout", "fresh"), help="the held-out set (default heldout)")
    args = parser.parse_args()
    try:
        print("\n".join(table(args.runs, args.models, args.against, args.set)))
    except FileNotFoundError as exc:
        raise SystemExit(f"held_out_table.py: {exc.filename} is missing (touchanything eval ... --views all --out "
                         f"{Path(exc.filename).parent})") from None
    except OSError as exc:
        raise SystemExit(f"held_out_table.py: {exc.filename} cannot be read ({exc.strerror})") from None
    except (ValueError, KeyError, TypeError, StopIteration) as exc:
        raise SystemExit(f"held_out_table.py: a results.json under {args.runs} is not eval's all-views results "
                         f"({type(exc).__name__}: {exc})") from None


if __name__ == "__main__":
    main()
