"""Benchmark outputs: the target checks, a Markdown table, the JSON record and the Pareto plot (PNG)."""
from __future__ import annotations

import json
import math
from pathlib import Path

from touchanything.devices.output_safety import replacing, write_text

P99_TARGET_MS = 33.0
OUTPUT_FILES = ("engine.json", "engine.md", "engine_pareto.png")
"""What `bench` writes into its --out folder (on a GPU: GPU_OUTPUT_FILES instead)."""
GPU_OUTPUT_FILES = ("engine_gpu.json", "engine_gpu.md")
NAIVE_RATIO_TARGET = 5.0
PRECISION_LOSS_TARGET = 0.01


def _reference(rows: list[dict], preset: str) -> dict | None:
    return next((r for r in rows if r["preset"] == preset and r["runtime"] == "torch" and r["precision"] == "fp32"
                 and r["rate"] == 1 and r["output"] == "newest" and r["invalid_hands"] == "skip"
                 and r["views"].count("+") == 2 and r["volumetric_iou"] is not None and not r.get("blank")), None)


def _check(target: str, value: float | None, bound: float, at_most: bool) -> dict:
    met = None if value is None else (value <= bound if at_most else value >= bound)
    return {"target": target, "value": value, "limit": f"{'≤' if at_most else '≥'} {bound:g}", "met": met}


def target_checks(rows: list[dict], naive: dict, smallest: str) -> list[dict]:
    """The issue's three targets, each {target, value, limit, met} (value and met None when not measured);
    pose-only baselines are not settings to ship and are left out."""
    rows = [r for r in rows if not r.get("blank")]
    fast = next((r for r in rows if r["preset"] == smallest and r["runtime"] == "onnx" and r["precision"] == "int8"
                 and r["views"].count("+") == 2 and r["rate"] == 1 and r["output"] == "newest"), None)
    checks = [_check(f"{smallest} ONNX int8, all views: p99 per-frame latency (ms)", fast and fast["p99_ms"],
                     P99_TARGET_MS, at_most=True),
              _check("paper preset: naive per-frame time / streaming per-frame time",
                     naive.get("paper", {}).get("ratio"), NAIVE_RATIO_TARGET, at_most=False)]
    for row in rows:
        reference = _reference(rows, row["preset"])
        same_knobs = reference and all(row[k] == reference[k] for k in ("views", "rate", "output", "invalid_hands"))
        if row["precision"] in ("int8", "bf16") and same_knobs and row["volumetric_iou"] is not None:
            checks.append(_check(f"{row['label']}: volumetric IoU lost against fp32",
                                 reference["volumetric_iou"] - row["volumetric_iou"], PRECISION_LOSS_TARGET, at_most=True))
    return checks


def _fmt(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return f"{value:.{digits}f}" if isinstance(value, float) else str(value)


def markdown(record: dict) -> str:
    lines = ["# `touchanything bench`", "", f"{record['machine']}; {'quick' if record['quick'] else 'full'} run; "
             f"accuracy on {record['accuracy_data']}.", "",
             "| setting | p50 ms | p99 ms | frames/s | look-ahead ms | contact IoU | volumetric IoU | "
             "agreement V-IoU | max abs diff | peak RSS MB |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in record["rows"]:
        lines.append(f"| {r['label']} | {_fmt(r['p50_ms'], 1)} | {_fmt(r['p99_ms'], 1)} | {_fmt(r.get('throughput_fps'), 1)} | "
                     f"{_fmt(r['lookahead_ms'], 0)} | {_fmt(r['contact_iou'])} | {_fmt(r['volumetric_iou'])} | "
                     f"{_fmt(r['agreement_viou'])} | {_fmt(r.get('agreement_max_abs'))} | {_fmt(r['peak_rss_mb'], 0)} |")
    lines += ["", "## Streaming cache against the naive recompute (torch fp32, all views)", "",
              "| preset | naive ms/frame | streaming ms/frame | naive / streaming |", "|---|---|---|---|"]
    for preset, n in record["naive"].items():
        lines.append(f"| {preset} | {_fmt(n['naive_p50_ms'], 1)} | {_fmt(n['streaming_p50_ms'], 1)} | {_fmt(n['ratio'], 1)}× |")
    lines += vision_share_lines(record["rows"])
    lines += ["", "## Targets", "", "| target | measured | limit | met |", "|---|---|---|---|"]
    for c in record["targets"]:
        met = {True: "yes", False: "**no**", None: "not measured"}[c["met"]]
        lines.append(f"| {c['target']} | {_fmt(c['value'])} | {c['limit']} | {met} |")
    return "\n".join(lines) + "\n"


SHARE_COLUMNS = ("contact_iou", "volumetric_iou", "temporal_accuracy", "temporal_f1", "mae")


def vision_share_lines(rows: list[dict]) -> list[str]:
    """The vision share of each pose-only row's setting (none without them): (real − pose only) / max(real,
    pose only), MAE reversed (`inference/evaluation/vision_share.py`)."""
    blanks = [r for r in rows if r.get("blank")]
    if not blanks:
        return []
    lines = ["", "## Share carried by vision (against the pose-only baseline: every frame black)", "",
             "(real − pose only) / max(real, pose only); for MAE (pose only − real) / max; 1 = all from the images, "
             "0 = none, < 0 = better without them.", "",
             "| setting | " + " | ".join(SHARE_COLUMNS) + " |", "|---|" + "---|" * len(SHARE_COLUMNS)]
    for r in blanks:
        setting = r["label"].removesuffix(" pose only")
        lines.append(f"| {setting} | " + " | ".join(_fmt(r["vision_share"][k]) for k in SHARE_COLUMNS) + " |")
    return lines


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats on both latency (lower) and accuracy (higher)."""
    return [i for i, (x, y) in enumerate(points)
            if not any((a <= x and b >= y) and (a < x or b > y) for a, b in points)]


MIN_ACCURACY_SPAN = 0.02
"""The plot's accuracy axis spans at least this much, so that settings a few 1e-7 apart read as equal."""


def frontier_steps(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The Pareto frontier as a staircase through the front's points (latency ascending), run on to the slowest
    point's latency: below and right of it every setting is beaten. One front point gives a flat line."""
    front = sorted(points[i] for i in pareto_front(points))
    if not front:
        return []
    steps = [front[0]]
    for x, y in front[1:]:
        steps += [(x, steps[-1][1]), (x, y)]
    right = max(x for x, _ in points)
    return steps + [(right, front[-1][1])] if right > steps[-1][0] else steps


def pareto_figure(rows: list[dict]):
    """The latency / accuracy plot of the rows with both measured (a matplotlib Figure): one colour per preset,
    the frontier, plain tick labels on both axes (no offset notation)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    measured = [r for r in rows if r["volumetric_iou"] is not None and not math.isnan(r["volumetric_iou"])
                and r["p99_ms"] is not None]
    points = [(r["p99_ms"], r["volumetric_iou"]) for r in measured]
    fig, ax = plt.subplots(figsize=(9, 6), dpi=110)
    for preset in sorted({r["preset"] for r in measured}):
        chosen = [p for p, r in zip(points, measured) if r["preset"] == preset]
        ax.scatter(*zip(*chosen), label=preset, s=28)
    if steps := frontier_steps(points):
        ax.plot(*zip(*steps), "k--", lw=1, label="Pareto frontier")
    for (x, y), r in zip(points, measured):
        ax.annotate(r["label"].split(" ", 1)[1], (x, y), fontsize=6, xytext=(3, 2), textcoords="offset points")
    ax.axvline(P99_TARGET_MS, color="grey", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.xaxis.set_minor_formatter(matplotlib.ticker.ScalarFormatter())
    if points:
        low, high = min(y for _, y in points), max(y for _, y in points)
        pad = max(MIN_ACCURACY_SPAN - (high - low), 0.0) / 2 + 0.05 * (high - low)
        ax.set_ylim(low - pad, high + pad)
    ax.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter(useOffset=False))
    ax.set_xlabel("p99 per-frame engine latency (ms, log scale)")
    ax.set_ylabel("volumetric IoU (official, held-out episodes)")
    ax.set_title("TouchAnything streaming engine: latency against accuracy")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def pareto_plot(rows: list[dict], path: Path) -> None:
    """`pareto_figure` saved as PNG."""
    import matplotlib.pyplot as plt

    fig = pareto_figure(rows)
    fig.savefig(path, format="png")
    plt.close(fig)


def write_outputs(record: dict, out_dir: Path) -> list[Path]:
    """OUTPUT_FILES into `out_dir`, each under the output rule (output_safety.replacing)."""
    paths = [out_dir / name for name in OUTPUT_FILES]
    write_text(paths[0], json.dumps(record, indent=1) + "\n")
    write_text(paths[1], markdown(record))
    with replacing(paths[2]) as temporary:
        pareto_plot(record["rows"], temporary)
    return paths
