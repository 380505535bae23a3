"""A small atlas file (the rows `touchanything bench` writes) for the bundled models as they are here."""
from __future__ import annotations

import json
from pathlib import Path

from touchanything.app.sessions.bundled import bundled_models
from touchanything.inference.evaluation.atlas import file_sha256


def atlas_row(setting: str, sha: str, viou: float, p99: float) -> dict:
    return {"setting": setting, "model": setting.split("/")[0], "checkpoint_sha256": sha, "trajectories": 108,
            "p99_ms": p99, "volumetric_iou": viou, "volumetric_iou_ci95": [viou - 0.02, viou + 0.02],
            "contact_iou": viou + 0.1, "contact_iou_ci95": [viou + 0.08, viou + 0.12], "blank": False}


def write_atlas(path: Path) -> Path:
    """Three settings of the bundled nano and baseline_pose with their real weights' sha256, a model that is not
    here, a pose-only twin and a latency-only row (the last three are never candidates)."""
    shas = {name: file_sha256(checkpoint) for name, checkpoint in bundled_models().items()}
    rows = [atlas_row("nano/torch-fp32/all", shas["nano"], 0.60, 8.0), atlas_row("nano/onnx-int8/ego", shas["nano"], 0.55, 3.0),
            atlas_row("baseline_pose/onnx-int8/all", shas["baseline_pose"], 0.50, 1.0),
            atlas_row("gone/torch-fp32/all", "0" * 64, 0.9, 1.0),
            dict(atlas_row("nano/torch-fp32/all/pose-only", shas["nano"], 0.4, 8.0), blank=True),
            {"setting": "paper/torch-fp32/all", "model": "paper", "p99_ms": 900.0, "volumetric_iou": None}]
    path.write_text(json.dumps({"rows": rows}))
    return path
