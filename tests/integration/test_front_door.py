"""`import touchanything`: the public surface, and the README's example run as written."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

import touchanything

ROOT = Path(__file__).resolve().parents[2]


def readme_example() -> str:
    """The Python block of the README's "From Python" section."""
    section = (ROOT / "README.md").read_text().split("## From Python", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


CONSTANTS = {
    "VIEW_NAMES": ("ego", "wrist_left", "wrist_right"),
    "METRICS": ("temporal_accuracy", "contact_iou", "volumetric_iou", "mae", "mae_left", "mae_right"),
}
"""The public constants' values, written out from the official names (reference/official_data.md)."""


def test_every_public_name_resolves_and_nothing_private_is_listed():
    assert len(touchanything.__all__) == len(set(touchanything.__all__))
    for name in touchanything.__all__:
        assert not name.startswith("_")
        value = getattr(touchanything, name)
        if name in CONSTANTS:
            assert value == CONSTANTS[name], name
        elif name == "ALL_METRICS":
            assert value[:6] == CONSTANTS["METRICS"] and "temporal_f1" in value, value
        elif name == "PRESETS":
            assert {"paper", "tiny", "nano"} <= set(value), sorted(value)
        else:  # a class or function of the project's own, under the name it is listed by (not another object)
            assert value.__name__ == name and value.__module__.startswith("touchanything."), (name, value)
    try:
        touchanything.not_a_public_name  # noqa: B018 - the lazy lookup refuses names it does not list
    except AttributeError as exc:
        assert "not_a_public_name" in str(exc)
    else:
        raise AssertionError("an unlisted name resolved")
    assert {"load_model", "StreamingEngine", "EngineSetting", "Snapshot", "Prediction", "open_episode", "TactileLayout",
            "compute_tactile_metrics"} <= set(touchanything.__all__)


def test_the_front_door_loads_no_gui_or_command_line():
    probe = "import sys, touchanything; print(sorted(m for m in sys.modules if 'dearpygui' in m or '.commands' in m))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_readme_example_runs_from_any_folder(tmp_path):
    script = readme_example() + "\nimport json\nprint(json.dumps(ta.compute_tactile_metrics(predicted, measured, " \
                                "ta.TactileLayout.default().bend)))\nprint(len(predictions), episode.num_frames)\n" + BY_HAND
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.strip().splitlines()
    metrics = json.loads(lines[-3])
    frames, total = map(int, lines[-2].split())
    assert frames == total > 0
    assert set(touchanything.ALL_METRICS) <= set(metrics)
    for key, value in json.loads(lines[-1]).items():  # the example's figures, worked out again by hand
        assert metrics[key] == pytest.approx(value, abs=1e-9), key


BY_HAND = """
inside = ~np.isnan(measured)
p, m = np.where(inside, predicted, 0.0), np.where(inside, measured, 0.0)
on_p, on_m = p > 0.1, m > 0.1
tactile = inside & ~ta.TactileLayout.default().bend
kept = inside.any(axis=(1, 2, 3))
flags = [(on & tactile).sum(axis=(1, 2, 3))[kept] >= 0.05 * tactile.sum(axis=(1, 2, 3))[kept] for on in (on_p, on_m)]
p, m = p.astype(np.float64), m.astype(np.float64)
print(json.dumps({"volumetric_iou": np.minimum(p, m).sum() / np.maximum(p, m).sum(),
                  "contact_iou": float((on_p & on_m).sum() / (on_p | on_m).sum()),
                  "mae": float(np.abs(p - m)[inside].mean()),
                  "temporal_accuracy": float((flags[0] == flags[1]).mean())}))
"""
"""The volumetric IoU, contact IoU, MAE and temporal accuracy of the README's `predicted` and `measured`, with
plain numpy (the official protocol: the measured map's cells; contact strictly above 0.1; a frame in contact when
5 % of its measured non-bend cells are)."""
