"""The atlas's picture: per-frame p99 latency against held-out accuracy (volumetric and contact IoU) for every
setting with both measured, one colour per model, 95 % intervals as error bars, the Pareto frontier, and the
frontier's settings named."""
from __future__ import annotations

import math
from pathlib import Path

MIN_ACCURACY_SPAN = 0.02
"""The plot's accuracy axis spans at least this much, so that settings a few 1e-7 apart read as equal."""
PLOTTED_METRICS = (("volumetric_iou", "volumetric IoU"), ("contact_iou", "contact IoU"))


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats on both latency (lower) and accuracy (higher)."""
    return [i for i, (x, y) in enumerate(points)
            if not any((a <= x and b >= y) and (a < x or b > y) for a, b in points)]


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


LABEL_GAP = 0.05
"""A frontier setting is named unless a more accurate named one sits within this share of the accuracy axis
above it and within LABEL_WIDTH of its latency (their labels would overlap)."""
LABEL_WIDTH = 1.7
"""The latency ratio a 7-point setting name spans on the plot's log axis."""
EQUAL_ACCURACY = 0.001
"""Frontier settings closer than this in accuracy read as one: only the fastest of them is named."""


def named_front(points: list[tuple[float, float]], gap: float) -> list[int]:
    """The frontier points to name on the plot (`gap`: accuracy units, LABEL_GAP of the axis): most accurate
    first, the fastest of each group within EQUAL_ACCURACY, skipping a point whose label would overlap a named
    one's."""
    front, named = pareto_front(points), []
    for i in sorted(front, key=lambda i: -points[i][1]):
        x, y = points[i]
        faster_equal = any(points[j][0] < x and y - points[j][1] < EQUAL_ACCURACY for j in front)
        crowded = any(points[j][1] - y < gap and max(x, points[j][0]) < LABEL_WIDTH * min(x, points[j][0])
                      for j in named)
        if not faster_equal and not crowded:
            named.append(i)
    return named


def plotted_rows(rows: list[dict]) -> list[dict]:
    """The settings a user can run that have a p99 latency and a finite volumetric IoU (pose-only twins left out)."""
    return [r for r in rows if not r.get("blank") and r.get("p99_ms") is not None
            and isinstance(r.get("volumetric_iou"), float) and math.isfinite(r["volumetric_iou"])]


def _error_bars(rows: list[dict], metric: str) -> list[list[float]] | None:
    """[[below…], [above…]] distances of each row's 95 % interval from its value (None when no row has one)."""
    if not any(r.get(f"{metric}_ci95") for r in rows):
        return None
    below, above = [], []
    for r in rows:
        low, high = r.get(f"{metric}_ci95") or (r[metric], r[metric])
        below.append(max(r[metric] - (low if low is not None else r[metric]), 0.0))
        above.append(max((high if high is not None else r[metric]) - r[metric], 0.0))
    return [below, above]


def _panel(ax, rows: list[dict], metric: str, title: str, p99_target: float | None) -> None:
    import matplotlib.ticker

    points = [(r["p99_ms"], r[metric]) for r in rows]
    colours = {model: f"C{i}" for i, model in enumerate(dict.fromkeys(r["model"] for r in rows))}
    for model, colour in colours.items():
        chosen = [r for r in rows if r["model"] == model]
        bars = _error_bars(chosen, metric)
        ax.errorbar([r["p99_ms"] for r in chosen], [r[metric] for r in chosen], yerr=bars, fmt="o", ms=4, lw=0.8,
                    capsize=2, color=colour, label=model, alpha=0.85)
    if steps := frontier_steps(points):
        ax.plot(*zip(*steps), "k--", lw=1, label="Pareto frontier")
    if p99_target is not None:
        ax.axvline(p99_target, color="grey", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.xaxis.set_minor_formatter(matplotlib.ticker.ScalarFormatter())
    ax.tick_params(axis="x", which="minor", labelsize=7)
    if points:
        values = [y for _, y in points] + [v for r in rows for v in (r.get(f"{metric}_ci95") or ()) if v is not None]
        low, high = min(values), max(values)
        pad = max(MIN_ACCURACY_SPAN - (high - low), 0.0) / 2 + 0.08 * (high - low)
        ax.set_ylim(low - pad, high + pad)
        for i in named_front(points, LABEL_GAP * (high - low + 2 * pad)):
            ax.annotate(rows[i]["setting"], points[i], fontsize=7, xytext=(4, -10), textcoords="offset points")
    ax.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter(useOffset=False))
    ax.set_xlabel("p99 per-frame engine latency (ms, log scale)")
    ax.set_ylabel(f"{title} (official, held-out)")
    ax.grid(True, which="major", lw=0.3, alpha=0.5)


def pareto_figure(rows: list[dict], subtitle: str = "", p99_target: float | None = None):
    """The latency / accuracy plot (a matplotlib Figure): one panel per metric of `PLOTTED_METRICS`, plain tick
    labels on both axes (no offset notation)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measured = plotted_rows(rows)
    fig, axes = plt.subplots(1, len(PLOTTED_METRICS), figsize=(14, 6.5), dpi=100)
    for ax, (metric, title) in zip(axes, PLOTTED_METRICS):
        _panel(ax, [r for r in measured if isinstance(r.get(metric), float) and math.isfinite(r[metric])], metric,
               title, p99_target)
    axes[0].legend(fontsize=8, loc="lower right")
    fig.suptitle("TouchAnything streaming engine: latency against accuracy (95 % intervals)"
                 + (f"\n{subtitle}" if subtitle else ""), fontsize=11)
    fig.tight_layout()
    return fig


def pareto_plot(rows: list[dict], path: Path, subtitle: str = "", p99_target: float | None = None) -> None:
    """`pareto_figure` saved as PNG."""
    import matplotlib.pyplot as plt

    fig = pareto_figure(rows, subtitle, p99_target)
    fig.savefig(path, format="png")
    plt.close(fig)
