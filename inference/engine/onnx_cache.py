"""The user cache of ONNX exports, `~/.cache/touchanything/onnx/<first 16 digits of the weights' SHA-256>/`,
filled on first use by an export in a child process at low priority (`export_aside`).

Why a child process: an export is seconds of Python (the torch exporter, then the int8 quantiser). Run on the
thread that loads a model while an engine runs (the dashboard's tier switch), it held the interpreter lock
and the cores at normal priority while the engine thread runs niced (`live_engine.ENGINE_NICENESS`): the
first switch to an ONNX tier not yet exported dropped 128 frames and reached 638 ms latency (issue 37). The
child has its own interpreter and runs below the engine (`EXPORT_NICENESS`); the loading thread only waits.
Run as `python -m touchanything.inference.engine.onnx_cache HANDOFF FOLDER` by `export_aside` only."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import torch

from touchanything.devices.errors import UserError
from touchanything.inference.engine.onnx_export import export_onnx
from touchanything.inference.model.model_config import config_from_dict, config_to_dict
from touchanything.inference.model.models import TactileModel, create_model

EXPORT_NICENESS = 12
"""Above the engine thread's nice +8: the export gets the CPU the engine, capture and display leave."""


def onnx_cache_dir(weights: str) -> Path:
    """The user cache's export of the model whose weights' SHA-256 is `weights` (named by its first 16 digits)."""
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return root / "touchanything" / "onnx" / weights[:16]


def export_aside(model: TactileModel, folder: Path) -> None:
    """Export `model` (fp32 and int8) into `folder`, replacing what it held, in a child Python process at nice
    `EXPORT_NICENESS`; the calling thread waits. UserError (one line) when the child fails."""
    with tempfile.TemporaryDirectory(prefix="touchanything-export-") as scratch:
        handoff = Path(scratch) / "model.pt"
        torch.save({"config": config_to_dict(model.config), "state": model.state_dict()}, handoff)
        child = subprocess.run([sys.executable, "-m", __name__, str(handoff), str(folder)], capture_output=True, text=True)
    if child.returncode != 0:
        last = (child.stderr.strip().splitlines() or [f"exit status {child.returncode}"])[-1]
        raise UserError(f"{folder}: exporting the ONNX graphs into the cache failed: {last.removeprefix(f'{folder}: ')}")


def _export_handoff(handoff: Path, folder: Path) -> None:
    """The child's side of `export_aside`: rebuild the model from the handoff file and export it."""
    os.nice(EXPORT_NICENESS)
    data = torch.load(handoff, map_location="cpu", weights_only=True)
    model = create_model(config_from_dict(data["config"], str(handoff)))
    model.load_state_dict(data["state"], strict=True)
    export_onnx(model.eval(), folder, int8=True, overwrite=True)


if __name__ == "__main__":
    try:
        _export_handoff(Path(sys.argv[1]), Path(sys.argv[2]))
    except UserError as exc:
        sys.exit(str(exc))
