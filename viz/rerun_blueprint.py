"""The default Rerun layout of a recording (`viz.rerun_recording`), arranged like the dashboard: the three
cameras on top; the measured, predicted (an ensemble's: and the members' spread) and difference maps (all but the
difference with their values beneath: hover a cell) beside the pressure painted on the 3D hands (measured |
predicted: the same surfaces, each view with its own paint, `viz.rerun_hands.paint_overrides`) in the middle; the
official metrics, the latency, the contact flags and the trackers at the bottom. The time panel follows the
`frame` timeline."""
from __future__ import annotations

import rerun.blueprint as rrb

from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.view_sets import VIEW_LABELS
from touchanything.viz.pressure_panel import MAP_TITLES, SPREAD_TITLE
from touchanything.viz.rerun_hands import paint_overrides

SHOWN_METRICS = ("temporal_accuracy", "contact_iou", "volumetric_iou", "mae")
"""The official metrics logged per frame (rolling over 3 s and cumulative)."""
MAP_ENTITIES = {"measured": "measured", "predicted": "predicted", "error": "difference"}
"""The maps' `pressure/…` entities."""
SPREAD_ENTITY = "spread"
"""An ensemble's spread map's `pressure/…` entity."""


def _hands(kind: str, title: str) -> rrb.Spatial3DView:
    return rrb.Spatial3DView(origin="world", contents=["+ world/hands/**", "+ world/surface/**"], name=title,
                             overrides=paint_overrides(kind))


def default_blueprint(spread: bool = False) -> rrb.Blueprint:
    """The layout; `spread`: with the ensemble's spread map (`pressure/spread`) under the predicted one."""
    cameras = rrb.Horizontal(*(rrb.Spatial2DView(origin=f"cameras/{view}", name=VIEW_LABELS[view]) for view in VIEW_NAMES))
    shown = [(MAP_ENTITIES[name], MAP_TITLES[name]) for name in ("measured", "predicted")]
    shown += [(SPREAD_ENTITY, SPREAD_TITLE)] if spread else []
    shown += [(MAP_ENTITIES["error"], MAP_TITLES["error"])]
    maps = rrb.Vertical(*(rrb.Spatial2DView(origin=f"pressure/{entity}", name=f"{title} (left | right)")
                          for entity, title in shown))
    hands = rrb.Horizontal(*(_hands(kind, f"{MAP_TITLES[kind]} on the hands") for kind in ("measured", "predicted")))
    plots = rrb.Horizontal(
        rrb.TimeSeriesView(origin="metrics", name="official metrics (3 s and all)"),
        rrb.TimeSeriesView(origin="engine", name="latency and engine step (ms)"),
        rrb.TimeSeriesView(origin="contact", name="contact (official rule per hand)"),
        rrb.Spatial3DView(origin="trackers", name="trackers"),
    )
    layout = rrb.Vertical(cameras, rrb.Horizontal(maps, hands, column_shares=[1, 2]), plots, row_shares=[3, 4, 2])
    return rrb.Blueprint(layout, rrb.TimePanel(timeline="frame"))
