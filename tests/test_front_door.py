"""`import touchanything`: the public surface, and the README's example run as written."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import touchanything

ROOT = Path(__file__).resolve().parents[1]


def readme_example() -> str:
    """The Python block of the README's "From Python" section."""
    section = (ROOT / "README.md").read_text().split("## From Python", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_every_public_name_resolves_and_nothing_private_is_listed():
    assert len(touchanything.__all__) == len(set(touchanything.__all__))
    for name in touchanything.__all__:
        assert getattr(touchanything, name) is not None and not name.startswith("_")
    assert {"load_model", "StreamingEngine", "EngineConfig", "Snapshot", "Prediction", "open_episode", "TactileLayout",
            "compute_tactile_metrics"} <= set(touchanything.__all__)


def test_the_front_door_loads_no_gui_or_command_line():
    probe = "import sys, touchanything; print(sorted(m for m in sys.modules if 'dearpygui' in m or '.commands' in m))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_readme_example_runs_from_any_folder(tmp_path):
    script = readme_example() + "\nimport json\nprint(json.dumps(ta.compute_tactile_metrics(predicted, measured, " \
                                "ta.TactileLayout.default().bend)))\nprint(len(predictions), episode.num_frames)\n"
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.strip().splitlines()
    metrics = json.loads(lines[-2])
    frames, total = map(int, lines[-1].split())
    assert frames == total > 0
    assert set(touchanything.ALL_METRICS) <= set(metrics)
    assert 0.0 <= metrics["temporal_accuracy"] <= 1.0 and metrics["mae"] < 1.0
