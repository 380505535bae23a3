"""Benchmark outputs: the target checks, a Markdown table with every accuracy's interval and the paired
differences, the JSON record (NaN written as null) and the Pareto plot (PNG)."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

from touchanything.core.output_safety import replacing, write_text
from touchanything.inference.evaluation.bench_plot import pareto_plot
from touchanything.inference.evaluation.bootstrap import thin_strata

P99_TARGET_MS = 33.0
OUTPUT_FILES = ("engine.json", "engine.md", "engine_pareto.png")
"""What `bench` writes into its --out folder (on a GPU: GPU_OUTPUT_FILES instead)."""
GPU_OUTPUT_FILES = ("engine_gpu.json", "engine_gpu.md")
NAIVE_RATIO_TARGET = 5.0
PRECISION_LOSS_TARGET = 0.01


def _reference(rows: list[dict], model: str) -> dict | None:
    return next((r for r in rows if r["setting"] == f"{model}/torch-fp32/all" and r["volumetric_iou"] is not None), None)


def _check(target: str, value: float | None, bound: float, at_most: bool) -> dict:
    met = None if value is None else (value <= bound if at_most else value >= bound)
    return {"target": target, "value": value, "limit": f"{'≤' if at_most else '≥'} {bound:g}", "met": met}


def target_checks(rows: list[dict], naive: dict, smallest: str, base: str = "nano",
                  comparisons: list[dict] = ()) -> list[dict]:
    """The engine's targets, each {target, value, limit, met} (value and met None when not measured); pose-only
    twins are not settings to ship and are left out. Beside the base model: a model faster than it (ONNX int8,
    all views) must reach FAST_P99_MS and beat `baseline_pose` in contact IoU (its paired interval above 0); a
    model more accurate than it must reach UNSEEN_VIOU_TARGET on unseen objects with its interval above the base
    model's value (its own interval, and the paired interval of the difference)."""
    rows = [r for r in rows if not r.get("blank")]
    fast = next((r for r in rows if r["setting"] == f"{smallest}/onnx-int8/all"), None)
    checks = [_check(f"{smallest} ONNX int8, all views: p99 per-frame latency (ms)", fast and fast["p99_ms"],
                     P99_TARGET_MS, at_most=True),
              _check("paper preset: naive per-frame time / streaming per-frame time",
                     naive.get("paper", {}).get("ratio"), NAIVE_RATIO_TARGET, at_most=False)]
    for row in rows:
        reference = _reference(rows, row["model"])
        same_knobs = reference and all(row[k] == reference[k] for k in ("views", "every", "output", "invalid_hands"))
        if row["precision"] in ("int8", "bf16") and same_knobs and row["volumetric_iou"] is not None:
            checks.append(_check(f"{row['setting']}: volumetric IoU lost against fp32",
                                 reference["volumetric_iou"] - row["volumetric_iou"], PRECISION_LOSS_TARGET, at_most=True))
    return checks + model_axis_checks(rows, base, list(comparisons))


FAST_P99_MS = 1.5
UNSEEN_VIOU_TARGET = 0.52
POSE_BASELINE = "baseline_pose"


def _unseen(row: dict) -> dict:
    return (row.get("per_split") or {}).get("test_unseen") or {}


def model_axis_checks(rows: list[dict], base: str, comparisons: list[dict]) -> list[dict]:
    """The model axis of the atlas against `base`: for each model with a faster ONNX int8 all-views setting, its p99
    against FAST_P99_MS and its contact IoU against the pose-only MLP (the lower bound of the paired difference of
    the two references, which must be > 0); for each model with a higher unseen-object V-IoU, that value against
    UNSEEN_VIOU_TARGET and the lower bound of its interval against the base's value (must be above it)."""
    by_setting = {r["setting"]: r for r in rows}
    base_fast, base_ref = by_setting.get(f"{base}/onnx-int8/all"), _reference(rows, base)
    checks = []
    for model in dict.fromkeys(r["model"] for r in rows):
        fast, ref = by_setting.get(f"{model}/onnx-int8/all"), _reference(rows, model)
        if model in (base, POSE_BASELINE) or model.startswith("baseline") or ref is None:
            continue
        if fast and base_fast and fast["p99_ms"] is not None and base_fast["p99_ms"] is not None \
                and fast["p99_ms"] < base_fast["p99_ms"]:
            checks.append(_check(f"{model} (faster than {base}): ONNX int8 all views p99 (ms)", fast["p99_ms"], FAST_P99_MS,
                                 at_most=True))
            against = next((c for c in comparisons if c["setting"] == ref["setting"]
                            and c["against"] == f"{POSE_BASELINE}/torch-fp32/all"), None)
            checks.append(_check(f"{model}: contact IoU minus {POSE_BASELINE}'s, low end of the paired 95 % interval",
                                 against and against["delta_contact_iou"][1], 0.0, at_most=False))
        unseen, base_unseen = _unseen(ref), _unseen(base_ref or {})
        if unseen and base_unseen and unseen["volumetric_iou"] > base_unseen["volumetric_iou"]:
            checks.append(_check(f"{model} (more accurate than {base}): V-IoU on unseen objects", unseen["volumetric_iou"],
                                 UNSEEN_VIOU_TARGET, at_most=False))
            checks.append(_check(f"{model}: low end of its unseen V-IoU interval minus {base}'s unseen V-IoU",
                                 unseen["volumetric_iou_ci95"][0] - base_unseen["volumetric_iou"], 0.0, at_most=False))
            paired = next((c for c in comparisons if c["setting"] == ref["setting"]
                           and c["against"] == base_ref["setting"]), None)
            low = paired and (paired.get("per_split") or {}).get("test_unseen", {}).get("delta_volumetric_iou", [None] * 3)[1]
            checks.append(_check(f"{model}: low end of the paired interval of its unseen V-IoU minus {base}'s", low, 0.0,
                                 at_most=False))
    return checks


def _fmt(value, digits: int = 3) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return _rounded(value, digits) if isinstance(value, float) else str(value)


def _rounded(value: float, digits: int = 3, sign: str = "") -> str:
    """`value` to `digits` places, never "-0.000" (a tiny negative rounds to zero, shown unsigned or "+")."""
    return f"{round(value, digits) + 0.0:{sign}.{digits}f}"


def _with_interval(value, interval) -> str:
    """"0.552 [0.531, 0.573]", or the value alone without an interval."""
    if not interval or any(v is None or math.isnan(v) for v in interval):
        return _fmt(value)
    return f"{_fmt(value)} [{_rounded(interval[0])}, {_rounded(interval[1])}]"


def _signed(entry: list[float]) -> str:
    mean, low, high = entry
    if any(v is None or math.isnan(v) for v in entry):
        return "n/a"
    return f"{_rounded(mean, sign='+')} [{_rounded(low, sign='+')}, {_rounded(high, sign='+')}]"


def held_out_line(record: dict) -> str:
    """"108 held-out trajectories (67 test_seen, 41 test_unseen) of DATA" (or the run's plain episode count)."""
    trajectories = record.get("trajectories") or []
    counts: dict[str, int] = {}
    for t in trajectories:
        counts[t["split"]] = counts.get(t["split"], 0) + 1
    parts = ", ".join(f"{n} {split}" for split, n in counts.items())
    return f"{len(trajectories)} held-out trajectories ({parts}) of {record['accuracy_data']}"


def _thin_note(record: dict) -> list[str]:
    """A warning paragraph when a split has too few trajectories for its interval (`bootstrap.thin_strata`)."""
    thin = thin_strata([t["split"] for t in record.get("trajectories") or []])
    return [f"**Warning:** {thin}.", ""] if thin else []


def _split_cells(row: dict, splits: list[str]) -> list[str]:
    per = row.get("per_split") or {}
    return [_with_interval(per.get(s, {}).get("volumetric_iou"), per.get(s, {}).get("volumetric_iou_ci95")) for s in splits]


def markdown(record: dict) -> str:
    splits = list(dict.fromkeys(t["split"] for t in record.get("trajectories") or []))
    minutes = f", {record['seconds'] / 60:.0f} min" if record.get("seconds") else ""
    lines = ["# `touchanything bench`: the speed/accuracy atlas", "",
             f"{record['machine']}; {'quick' if record['quick'] else 'full'} run{minutes}; accuracy on "
             f"{held_out_line(record)}: official metrics per trajectory (causal, every frame replayed), their mean over "
             "trajectories, and a 95 % bootstrap interval (2000 draws of the trajectories, within each split).", "",
             *_thin_note(record),
             "| setting | p50 ms | p99 ms | frames/s | look-ahead ms | volumetric IoU [95 % CI] | contact IoU [95 % CI] | "
             + "".join(f"V-IoU {s} | " for s in splits) + "agreement V-IoU | peak RSS MB |",
             "|---|---|---|---|---|---|---|" + "---|" * len(splits) + "---|---|"]
    for r in record["rows"]:
        lines.append(f"| {r['setting']} | {_fmt(r['p50_ms'], 1)} | {_fmt(r['p99_ms'], 1)} | {_fmt(r.get('throughput_fps'), 0)} | "
                     f"{_fmt(r['lookahead_ms'], 0)} | {_with_interval(r['volumetric_iou'], r.get('volumetric_iou_ci95'))} | "
                     f"{_with_interval(r['contact_iou'], r.get('contact_iou_ci95'))} | "
                     + "".join(f"{c} | " for c in _split_cells(r, splits))
                     + f"{_fmt(r['agreement_viou'])} | {_fmt(r['peak_rss_mb'], 0)} |")
    lines += comparison_lines(record.get("comparisons") or [])
    lines += ["", "## Streaming cache against the naive recompute (torch fp32, all views)", "",
              "| model | naive ms/frame | streaming ms/frame | naive / streaming |", "|---|---|---|---|"]
    for model, n in record["naive"].items():
        lines.append(f"| {model} | {_fmt(n['naive_p50_ms'], 1)} | {_fmt(n['streaming_p50_ms'], 1)} | {_fmt(n['ratio'], 1)}× |")
    lines += vision_share_lines(record["rows"])
    lines += spread_error_lines(record["rows"])
    lines += ["", "## Targets", "", "| target | measured | limit | met |", "|---|---|---|---|"]
    for c in record["targets"]:
        met = {True: "yes", False: "**no**", None: "not measured"}[c["met"]]
        lines.append(f"| {c['target']} | {_fmt(c['value'])} | {c['limit']} | {met} |")
    return "\n".join(lines) + "\n"


def _section(title: str, text: str, columns: list[str]) -> list[str]:
    """A report section's opening: its title, what it shows and its table's header."""
    return ["", f"## {title}", "", text, "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]


def comparison_lines(comparisons: list[dict]) -> list[str]:
    """The paired differences (`bench_intervals.paired_comparisons`) as a table (none without them)."""
    if not comparisons:
        return []
    lines = _section("Paired differences on the same trajectories",
                     "Each setting against its model's reference (torch fp32, all views, newest frame), and each model's "
                     "reference against the base model's: the difference of the means and its 95 % paired bootstrap "
                     "interval. An interval that holds 0 is no measured difference.",
                     ["setting", "against", "Δ volumetric IoU [95 % CI]", "Δ contact IoU [95 % CI]"])
    for c in comparisons:
        lines.append(f"| {c['setting']} | {c['against']} | {_signed(c['delta_volumetric_iou'])} | "
                     f"{_signed(c['delta_contact_iou'])} |")
    return lines


def spread_error_lines(rows: list[dict]) -> list[str]:
    """Whether each ensemble row's uncertainty map means something (none without ensembles): the mean over
    trajectories of the per-frame rank correlation of the members' spread with the error (`spread_error`), its 95 %
    interval and the trajectories that have one."""
    ensembles = [r for r in rows if r.get("spread_error_rho_ci95") is not None]
    if not ensembles:
        return []
    lines = _section("Does the ensemble's spread mean something?",
                     "Per frame, the rank correlation (Spearman) of the members' spread with the absolute error over the "
                     "predicted cells, averaged over each trajectory's frames, then over trajectories: > 0, the spread "
                     "is larger where the error is; an interval that holds 0, no measured relation.",
                     ["setting", "spread–error ρ [95 % CI]", "trajectories"])
    for r in ensembles:
        count = sum(1 for v in r["per_trajectory"]["spread_error_rho"] if v == v)  # not NaN
        lines.append(f"| {r['setting']} | {_with_interval(r['spread_error_rho'], r['spread_error_rho_ci95'])} | {count} |")
    return lines


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
        setting = r["setting"].removesuffix("/pose-only")
        lines.append(f"| {setting} | " + " | ".join(_fmt(r["vision_share"][k]) for k in SHARE_COLUMNS) + " |")
    return lines


def json_safe(value):
    """`value` with every non-finite float as None (JSON has no NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


_NUMBER_LIST = re.compile(r"\[\s*((?:-?[0-9.eE+-]+|null)(?:,\s*(?:-?[0-9.eE+-]+|null))*)\s*\]")


def record_json(record: dict) -> str:
    """The record as indented JSON (NaN as null), each list of numbers on one line."""
    text = json.dumps(json_safe(record), indent=1)
    return _NUMBER_LIST.sub(lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text) + "\n"


def write_outputs(record: dict, out_dir: Path) -> list[Path]:
    """OUTPUT_FILES into `out_dir`, each under the output rule (output_safety.replacing)."""
    paths = [out_dir / name for name in OUTPUT_FILES]
    write_text(paths[0], record_json(record))
    write_text(paths[1], markdown(record))
    with replacing(paths[2]) as temporary:
        pareto_plot(record["rows"], temporary, f"{record['machine']}; {held_out_line(record)}")
    return paths
