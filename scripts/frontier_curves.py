"""The frontier's three curves as docs/findings.md shows them: held-out accuracy against the number of training
trajectories (`pico` and `nano`), against the input resolution (`pico`) and against the ensemble's size K, each
point's volumetric and contact IoU paired against the bundled `pico` on the same trajectories, with 95 % intervals.

    .venv/bin/python scripts/frontier_curves.py data/runs --set heldout --plot docs/bench/frontier_curves_heldout.png

reads the runs of scripts/train_frontier.sh (RUNS/<run>/<set>_<split>/results.json, as scripts/held_out_table.py
does; a run not evaluated yet is left out, said on stderr) and, for K, the ensemble's bench reports
(docs/bench/ensemble_seeds_<set>.json for K = 3, docs/bench/ensemble_k4_<set>.json for K = 1, 2 and 4: their torch
fp32 all-view settings, paired against the same report's K = 1, the bundled `pico` run by the bench's engine). Prints Markdown; --plot
writes the picture (one panel per axis, Δ volumetric IoU with its interval, the target +0.03 dashed).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from held_out_table import METRICS, per_trajectory

from touchanything.inference.evaluation.bootstrap import Resampler

REFERENCE = "bundled_pico"
TRAINING_DATA = {  # capacity: {split file (its train list's length is the x): run}
    "pico": {"split_train.json": "pico_162", "split_train_more.json": REFERENCE, "split_train_2x.json": "pico_2x",
             "split_train_3x.json": "pico_3x"},
    "nano": {"split_train.json": "bundled_nano", "split_train_more.json": "nano_more", "split_train_2x.json": "nano_2x"},
}
RESOLUTION = {"pico": {64: REFERENCE, 96: "pico_96", 128: "pico_128"}}
ENSEMBLE_REPORTS = {1: "ensemble_k4", 2: "ensemble_k4", 3: "ensemble_seeds", 4: "ensemble_k4"}  # K: docs/bench/<report>_<set>.json
ENSEMBLE_BASE = "pico_ens/torch-fp32/all"
TARGET = 0.03
"""The frontier's target: the most accurate setting within 33 ms beats today's `pico` by this much V-IoU, paired."""


def paired(values: dict[str, list[float]], reference: dict[str, list[float]], splits: list[str]) -> dict:
    """{metric: (mean, low, high) of the setting, and "delta_<metric>": the paired difference against the reference}."""
    resampler = Resampler(splits)
    out = {"trajectories": len(splits)}
    for metric, _ in METRICS:
        out[metric] = resampler.interval(values[metric])
        out[f"delta_{metric}"] = resampler.difference(values[metric], reference[metric])
    return out


def run_point(runs: Path, run: str, held_out: str) -> dict | None:
    """The run's paired point against REFERENCE on the `held_out` set, or None when it is not evaluated yet."""
    try:
        data, reference = per_trajectory(runs, run, held_out), per_trajectory(runs, REFERENCE, held_out)
    except FileNotFoundError:
        print(f"{run}: not evaluated on data/{held_out} yet", file=sys.stderr)
        return None
    except (ValueError, KeyError, StopIteration) as exc:
        raise SystemExit(f"{runs / run} or {runs / REFERENCE}: a results.json on data/{held_out} is not eval's "
                         f"all-views results ({type(exc).__name__}: {exc})") from None
    paths = sorted(reference)
    if sorted(data) != paths:
        raise SystemExit(f"{run} and {REFERENCE} were evaluated on different trajectories of data/{held_out}")
    column = {m: [data[p][m] for p in paths] for m, _ in METRICS}
    return paired(column, {m: [reference[p][m] for p in paths] for m, _ in METRICS}, [reference[p]["split"] for p in paths])


def ensemble_point(bench: Path, k: int, held_out: str) -> dict | None:
    """The K-member ensemble's point from its bench report, paired against the report's K = 1 setting."""
    report_path = bench / f"{ENSEMBLE_REPORTS[k]}_{held_out}.json"
    if not report_path.is_file():
        print(f"K = {k}: {report_path} is missing", file=sys.stderr)
        return None
    setting = ENSEMBLE_BASE if k == 1 else f"{ENSEMBLE_BASE}/members{k}"
    try:
        report = json.loads(report_path.read_text())
        rows = {r["setting"]: r["per_trajectory"] for r in report["rows"] if r.get("per_trajectory")}
        splits = [t["split"] for t in report["trajectories"]]
        return paired(rows[setting], rows[ENSEMBLE_BASE], splits)
    except (ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"{report_path}: not a bench report with per-trajectory values of {setting} and "
                         f"{ENSEMBLE_BASE} ({type(exc).__name__}: {exc})") from None


def curves(runs: Path, data: Path, bench: Path, held_out: str) -> dict[str, dict[str, dict]]:
    """{axis: {curve: {x: point}}} for the three axes; points not measured yet are left out."""
    sizes = {}
    for name in {n for table in TRAINING_DATA.values() for n in table}:
        if (data / name).is_file():
            sizes[name] = len(json.loads((data / name).read_text())["train"])
        else:
            print(f"{data / name} is not written yet (scripts/make_datasets.sh)", file=sys.stderr)
    out: dict[str, dict[str, dict]] = {"training trajectories": {}, "input resolution (px)": {}, "ensemble members K": {}}
    for capacity, table in TRAINING_DATA.items():
        out["training trajectories"][capacity] = {
            sizes[name]: point for name, run in table.items() if name in sizes and (point := run_point(runs, run, held_out))}
    for capacity, table in RESOLUTION.items():
        out["input resolution (px)"][capacity] = {
            px: point for px, run in table.items() if (point := run_point(runs, run, held_out))}
    out["ensemble members K"]["pico"] = {
        k: point for k in ENSEMBLE_REPORTS if (point := ensemble_point(bench, k, held_out))}
    return out


def _cell(value: tuple[float, float, float], signed: bool = False) -> str:
    form = "+.3f" if signed else ".3f"
    return f"{value[0]:{form}} [{value[1]:{form}}, {value[2]:{form}}]"


def markdown(found: dict[str, dict[str, dict]]) -> list[str]:
    lines = ["| axis | model | x | trajectories | V-IoU | Δ V-IoU | C-IoU | Δ C-IoU |", "|---|---|---|---|---|---|---|---|"]
    for axis, table in found.items():
        for capacity, points in table.items():
            for x, p in sorted(points.items()):
                lines.append(f"| {axis} | {capacity} | {x} | {p['trajectories']} | {_cell(p['volumetric_iou'])} | "
                             f"{_cell(p['delta_volumetric_iou'], True)} | {_cell(p['contact_iou'])} | "
                             f"{_cell(p['delta_contact_iou'], True)} |")
    return lines


def plot(found: dict[str, dict[str, dict]], held_out: str, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(found), figsize=(4.2 * len(found), 3.6), sharey=True)
    for ax, (axis, table) in zip(axes, found.items()):
        for i, (capacity, points) in enumerate(table.items()):
            xs = sorted(points)
            mean = [points[x]["delta_volumetric_iou"][0] for x in xs]
            below = [m - points[x]["delta_volumetric_iou"][1] for m, x in zip(mean, xs)]
            above = [points[x]["delta_volumetric_iou"][2] - m for m, x in zip(mean, xs)]
            ax.errorbar(xs, mean, yerr=[below, above], marker="o", capsize=3, color=f"C{i}", label=capacity)
        ax.set_xticks(sorted({x for points in table.values() for x in points}))
        ax.axhline(0.0, color="grey", linewidth=0.8)
        ax.axhline(TARGET, color="grey", linewidth=0.8, linestyle="--")
        ax.set_xlabel(axis)
        ax.legend(loc="lower right", fontsize=8)
    axes[0].set_ylabel(f"Δ volumetric IoU against the bundled pico\n(paired, 95 % interval, data/{held_out})")
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(f".{out.name}.partial.png")
    figure.savefig(partial, dpi=110)
    partial.replace(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, help="the runs folder of scripts/train_frontier.sh (data/runs)")
    parser.add_argument("--set", default="heldout", choices=("heldout", "fresh"), help="the held-out set (default heldout)")
    parser.add_argument("--data", type=Path, default=Path("data"), help="where the split files lie (default data)")
    parser.add_argument("--bench", type=Path, default=Path("docs/bench"), help="the ensemble's bench reports (default docs/bench)")
    parser.add_argument("--plot", type=Path, help="write the picture here (PNG)")
    args = parser.parse_args()
    if not args.runs.is_dir():
        parser.error(f"{args.runs} is not a folder of runs")
    if args.plot and args.plot.suffix.lower() != ".png":
        parser.error(f"--plot {args.plot}: the picture is a PNG file; name it *.png")
    found = curves(args.runs, args.data, args.bench, args.set)
    print("\n".join(markdown(found)))
    if args.plot:
        plot(found, args.set, args.plot)


if __name__ == "__main__":
    main()
