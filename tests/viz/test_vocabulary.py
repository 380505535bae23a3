"""One vocabulary of view and panel names: the views' labels and ids (`core.view_sets`) and the maps' titles
(`viz.pressure_panel.MAP_TITLES`) are what the comparison video draws, what the Rerun blueprint names its views,
what `info` prints — and no module keeps its own copy. (The dashboard's titles and checkboxes:
tests/viz/test_dashboard_facts.py.)"""
from __future__ import annotations

import ast
from pathlib import Path

import cv2
import numpy as np
from rerun.blueprint.api import Container

from tests.integration.test_layout import module_files
from touchanything.app.cli import main
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.view_sets import VIEW_IDS, VIEW_LABELS, parse_view_set, view_set_name
from touchanything.viz.comparison_video import CAMERA_HEIGHT, PANEL_HEIGHT, comparison_frame
from touchanything.viz.pressure_panel import MAP_TITLES, pressure_panel, put_text
from touchanything.viz.rerun_blueprint import default_blueprint

VOCABULARY_MODULES = {"touchanything.core.view_sets", "touchanything.viz.pressure_panel"}
FILE_MAPS = {"touchanything.devices.episodes.raw_episode": "VIDEO_FILES", "touchanything.devices.episodes.hdf5_episode": "IMAGE_KEYS"}
"""Dicts keyed by the three views that map them to where they are stored (file names stay the official ones)."""


def test_the_labels_and_ids():
    assert VIEW_LABELS == {"ego": "head camera", "wrist_left": "left wrist camera", "wrist_right": "right wrist camera"}
    assert MAP_TITLES == {"measured": "measured pressure", "predicted": "predicted pressure", "error": "prediction − measured"}
    assert [view_set_name(v) for v in (("ego",), ("ego", "wrist_left"), ("wrist_right", "ego"), VIEW_NAMES)] == [
        "ego", "ego+left", "ego+right", "all"]
    assert view_set_name(("wrist_left", "wrist_right")) == "left+right" and view_set_name(()) == ""
    for views in (("ego",), ("wrist_left",), ("wrist_left", "wrist_right"), VIEW_NAMES):  # printed ids parse back
        assert parse_view_set(view_set_name(views)) == views
    assert [VIEW_IDS[v] for v in VIEW_NAMES] == ["ego", "left", "right"]


def _names(container) -> list[str]:
    """Every view's name in a blueprint container, depth first."""
    out = []
    for item in container.contents:
        out += _names(item) if isinstance(item, Container) else [item.name]
    return out


def test_the_rerun_blueprint_names_its_views_with_the_vocabulary():
    names = _names(default_blueprint().root_container)
    assert names[:3] == [VIEW_LABELS[v] for v in VIEW_NAMES]
    assert names[3:6] == [f"{MAP_TITLES[k]} (left | right)" for k in ("measured", "predicted", "error")]
    assert names[6:8] == [f"{MAP_TITLES[k]} on the hands" for k in ("measured", "predicted")]


def test_the_comparison_video_draws_the_vocabulary():
    rng = np.random.default_rng(0)
    images = {v: rng.integers(0, 255, (270, 480, 3), np.uint8) for v in VIEW_NAMES}
    grids = rng.uniform(0, 1, (2, 21, 21)).astype(np.float32)
    frame = comparison_frame(images, grids, grids, "footer")
    for k, view in enumerate(VIEW_NAMES):
        tile = cv2.resize(images[view], (480, CAMERA_HEIGHT), interpolation=cv2.INTER_AREA)
        put_text(tile, VIEW_LABELS[view], (8, 22), 0.6)
        assert np.array_equal(frame[:CAMERA_HEIGHT, 480 * k:480 * (k + 1)], tile), view
    panels = frame[CAMERA_HEIGHT:CAMERA_HEIGHT + PANEL_HEIGHT]
    bend = TactileLayout.default().bend  # the video draws bend cells as such
    assert np.array_equal(panels[:, :480], pressure_panel(grids, MAP_TITLES["measured"], 480, PANEL_HEIGHT, empty="no glove",
                                                          bend=bend))
    assert np.array_equal(panels[:, 480:960], pressure_panel(grids, MAP_TITLES["predicted"], 480, PANEL_HEIGHT,
                                                             empty="no pose", bend=bend))
    assert np.array_equal(panels[:, 960:], pressure_panel(grids - grids, MAP_TITLES["error"], 480, PANEL_HEIGHT, error=True,
                                                          bend=bend))


def test_info_prints_the_view_set_id_and_the_labels(episode_dir, capsys):
    assert main(["info", str(episode_dir)]) == 0
    assert ("views     all: head camera 64×48 (40 frames); left wrist camera 64×48 (40 frames); right wrist camera "
            "64×48 (40 frames)") in capsys.readouterr().out
    assert main(["info", str(episode_dir.parents[2])]) == 0
    assert ": 40 frames, views all, " in capsys.readouterr().out


def _strings(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, text) of every string constant that is not a docstring."""
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body
                  and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    docstrings |= {id(node.value) for node in ast.walk(tree)  # attribute docstrings: a string statement
                   if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)}
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings]


def test_no_module_keeps_its_own_view_labels_or_map_titles():
    """No string but in the vocabulary's modules starts with a label or a title (a title or label of its own; prose
    such as "hidden from the head camera" is fine), and no dict maps the three views to anything but files."""
    labels = tuple(text.lower() for text in (*VIEW_LABELS.values(), *MAP_TITLES.values()))
    found = []
    for module, path in module_files().items():
        tree = ast.parse(Path(path).read_text())
        if module not in VOCABULARY_MODULES:
            found += [f"{module}:{line}: {text!r}" for line, text in _strings(tree) if text.strip().lower().startswith(labels)]
        for node in ast.walk(tree):
            keys = {k.value for k in getattr(node, "keys", []) if isinstance(node, ast.Dict) and isinstance(k, ast.Constant)}
            if keys == set(VIEW_NAMES) and module not in VOCABULARY_MODULES and module not in FILE_MAPS:
                found.append(f"{module}:{node.lineno}: a dict keyed by the views")
    assert not found, "\n".join(found)
