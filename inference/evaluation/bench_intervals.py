"""The uncertainty of a bench run's accuracy: a 95 % bootstrap interval on every row's volumetric and contact IoU
(over all held-out trajectories and per split), and paired differences between settings measured on the same
trajectories (`bootstrap`): each setting against its model's reference (int8 against fp32, a view subset
against all views, a rate or output position against every frame's newest), and each model's reference
against the base model's (the default model: what a model adds or loses against it).

Rows carry their per-trajectory values (`bench.PER_TRAJECTORY_METRICS`) aligned with the run's trajectory list
(`align_rows`); a trajectory a model could not replay is NaN in its rows, which the official mean leaves out.
"""
from __future__ import annotations

import math

import numpy as np

from touchanything.inference.engine.engine_setting import EngineSetting, parse_setting
from touchanything.inference.evaluation.bench_setting import reference_of
from touchanything.inference.evaluation.bootstrap import Resampler

INTERVAL_METRICS = ("volumetric_iou", "contact_iou")
SPREAD_ERROR = "spread_error_rho"
"""An ensemble setting's per-trajectory rank correlation of its members' spread with its error (`spread_error`),
given an interval like INTERVAL_METRICS where a row has it."""


def align_rows(rows: list[dict], own: list[dict], trajectories: list[dict]) -> None:
    """Reorder each row's per-trajectory values from its model's trajectory list `own` to the run's list
    `trajectories` (NaN where the model has no value)."""
    where = {t["name"]: i for i, t in enumerate(own)}
    for row in rows:
        values = row.get("per_trajectory")
        if values is None:
            continue
        row["per_trajectory"] = {metric: [values[metric][where[t["name"]]] if t["name"] in where else math.nan
                                          for t in trajectories] for metric in values}


def _interval_fields(resampler: Resampler, values: dict[str, list[float]], keep: np.ndarray | None = None) -> dict:
    out = {}
    for metric in INTERVAL_METRICS + tuple(m for m in (SPREAD_ERROR,) if m in values):
        series = np.asarray(values[metric], np.float64)
        mean, low, high = resampler.interval(series if keep is None else series[keep])
        out[metric], out[f"{metric}_ci95"] = mean, [low, high]
    return out


def add_intervals(rows: list[dict], trajectories: list[dict]) -> None:
    """Set `<metric>_ci95` [low, high] on every row with per-trajectory values (its `<metric>` is the same official
    mean), and `per_split` {split: {trajectories, <metric>, <metric>_ci95}}; an ensemble's row also gets its mean
    spread–error rank correlation `spread_error_rho` (over the trajectories that have one) and its interval."""
    splits = [t["split"] for t in trajectories]
    resampler = Resampler(splits)
    per_split = {name: np.array([s == name for s in splits]) for name in dict.fromkeys(splits)}
    split_resamplers = {name: Resampler([name] * int(keep.sum())) for name, keep in per_split.items()}
    for row in rows:
        if row.get("per_trajectory") is None:
            continue
        row.update(_interval_fields(resampler, row["per_trajectory"]))
        row["per_split"] = {name: {"trajectories": int(keep.sum()),
                                   **_interval_fields(split_resamplers[name], row["per_trajectory"], keep)}
                            for name, keep in per_split.items()}


def paired_comparisons(rows: list[dict], trajectories: list[dict], base_models: tuple[str, ...]) -> list[dict]:
    """{setting, against, kind ("setting" | "model"), trajectories, delta_<metric>: [mean, low, high], per_split:
    {split: {delta_<metric>}}} for every row with accuracy against its reference setting, and every model's
    reference against each of `base_models`' (the default model, the pose-only baseline)."""
    resampler = Resampler([t["split"] for t in trajectories])
    measured = {row["setting"]: row for row in rows if row.get("per_trajectory") is not None}
    bases = [EngineSetting(model).name() for model in base_models]
    pairs = []
    for name in measured:
        setting = parse_setting(name)
        reference = reference_of(setting).name()
        if reference != name and reference in measured:
            pairs.append((name, reference, "setting"))
        elif reference == name and not setting.blank:
            pairs += [(name, base, "model") for base in bases if base != name and base in measured]
    splits = [t["split"] for t in trajectories]
    groups = {name: np.array([s == name for s in splits]) for name in dict.fromkeys(splits)}
    split_resamplers = {name: Resampler([name] * int(keep.sum())) for name, keep in groups.items()}
    out = []
    for name, against, kind in pairs:
        a, b = measured[name]["per_trajectory"], measured[against]["per_trajectory"]
        entry = {"setting": name, "against": against, "kind": kind, "trajectories": len(trajectories)}
        entry.update(_deltas(resampler, a, b))
        entry["per_split"] = {split: _deltas(split_resamplers[split], a, b, keep) for split, keep in groups.items()}
        out.append(entry)
    return out


def _deltas(resampler: Resampler, a: dict, b: dict, keep: np.ndarray | None = None) -> dict:
    """{delta_<metric>: [mean, low, high]} of the paired difference a − b (over the trajectories `keep`)."""
    out = {}
    for metric in INTERVAL_METRICS:
        x, y = np.asarray(a[metric], np.float64), np.asarray(b[metric], np.float64)
        if keep is not None:
            x, y = x[keep], y[keep]
        out[f"delta_{metric}"] = list(resampler.difference(x, y))
    return out
