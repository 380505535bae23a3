"""The one set of view names every command accepts: the official view names (`ego`, `wrist_left`,
`wrist_right`), their short forms (`left`, `right`), `+`-joined sets (`ego+left`) and `all`; and the official
evaluation's four view configurations (`ego`, `ego+left`, `ego+right`, `all`)."""
from __future__ import annotations

from touchanything.devices.snapshot import VIEW_NAMES

VIEW_ALIASES = {"ego": "ego", "wrist_left": "wrist_left", "left": "wrist_left", "wrist_right": "wrist_right",
                "right": "wrist_right"}
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
    """The official configuration name of a view set (`ego+left`, `all`), else its short names joined by `+`."""
    for name, members in VIEW_SETS.items():
        if set(members) == set(views):
            return name
    return "+".join(v.removeprefix("wrist_") for v in VIEW_NAMES if v in views)
