"""The views' vocabulary, in one place: the official view names (`ego`, `wrist_left`, `wrist_right`: the
model's and `Snapshot`'s), their ids in view-set ids (`ego`, `left`, `right`: what `--views` takes and what
every command prints: `ego+left`, `all`), the label user-facing text calls each one (the dashboard, the
comparison video, Rerun, `info`) and how it marks a view the model does not use ("left wrist camera — not
used"), and the official evaluation's four view configurations (`ego`, `ego+left`, `ego+right`, `all`). A raw
episode's files keep the official names: chest.mp4, left.mp4, right.mp4 (`devices.episodes.raw_episode.VIDEO_FILES`)."""
from __future__ import annotations

from touchanything.core.snapshot import VIEW_NAMES

VIEW_IDS = {"ego": "ego", "wrist_left": "left", "wrist_right": "right"}
"""Official view name → its id in view-set ids (`ego+left`)."""
VIEW_LABELS = {"ego": "head camera", "wrist_left": "left wrist camera", "wrist_right": "right wrist camera"}
"""Official view name → what every user-facing text calls it."""
NOT_USED = "not used"
"""What a view's label adds when the model takes nothing from that view (`view_label`)."""
VIEW_ALIASES = {**{view: view for view in VIEW_NAMES}, **{short: view for view, short in VIEW_IDS.items()}}
"""Every accepted spelling of one view → its official name."""
VIEW_SETS = {"ego": ("ego",), "ego+left": ("ego", "wrist_left"), "ego+right": ("ego", "wrist_right"), "all": VIEW_NAMES}
"""The official evaluation's view configurations (`inference_tactile_parallel.py --views`) → the views they use."""
VIEW_HELP = ("a view is ego, wrist_left (or left), wrist_right (or right); join views with + (ego+left); all = "
             "the three")


def parse_view_set(text: str) -> tuple[str, ...]:
    """The official views named by `text` (`all`, or views joined by `+` in any accepted spelling), in
    `VIEW_NAMES` order; raises ValueError naming the unknown part (argparse turns it into a usage error)."""
    if text == "all":
        return VIEW_NAMES
    parts = text.split("+")
    unknown = [p for p in parts if p not in VIEW_ALIASES]
    if unknown:
        raise ValueError(f"unknown view {unknown[0]!r} ({VIEW_HELP})")
    chosen = {VIEW_ALIASES[p] for p in parts}
    return tuple(v for v in VIEW_NAMES if v in chosen)


def view_set_name(views: tuple[str, ...]) -> str:
    """The id of a view set, as `--views` takes it: the official configuration's name (`ego+left`, `all`), else
    its views' ids joined by `+` (`left+right`; "" for no view)."""
    for name, members in VIEW_SETS.items():
        if set(members) == set(views):
            return name
    return "+".join(VIEW_IDS[v] for v in VIEW_NAMES if v in views)


def view_label(view: str, used: bool = True) -> str:
    """What user-facing text calls `view` (an official name): its label, and for a view the model does not use
    "left wrist camera — not used"."""
    return VIEW_LABELS[view] if used else f"{VIEW_LABELS[view]} — {NOT_USED}"


def views_used(views: tuple[str, ...], pose_only: bool) -> tuple[str, ...]:
    """The views a model given `views` takes anything from, in `VIEW_NAMES` order: none for a pose-only model
    (it sees black frames) and none without the head camera (no prediction without it)."""
    if pose_only or "ego" not in views:
        return ()
    return tuple(v for v in VIEW_NAMES if v in views)
