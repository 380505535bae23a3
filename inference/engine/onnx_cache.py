"""The user cache of ONNX exports, `~/.cache/touchanything/onnx/<first 16 digits of the weights' SHA-256>/`,
filled on first use by an export in a child process at low priority (`export_aside`).

Why a child process: an export is seconds of Python (the torch exporter, then the int8 quantiser). Run on the
thread that loads a model while an engine runs (the dashboard's tier switch), it held the interpreter lock
and the cores at normal priority while the engine thread runs niced (`live_engine.ENGINE_NICENESS`): the
first switch to an ONNX tier not yet exported dropped 128 frames and reached 638 ms latency. The
child has its own interpreter and runs below the engine (`EXPORT_NICENESS`); the loading thread only waits. A
command that waits for the export on its main thread (a headless replay) has nothing to protect: its child
runs at the command's priority (niced, a `pico` export on a busy machine took minutes), with the wait said.
Run as `python -m touchanything.inference.engine.onnx_cache HANDOFF FOLDER NICENESS` by `export_aside` only."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import torch
from tqdm import tqdm

from touchanything.core.errors import UserError
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
    """Export `model` (fp32 and int8) into `folder`, replacing what it held, in a child Python process; the
    calling thread waits. Called from a command's main thread, the child runs at the command's own priority
    and the wait is said on stderr with the seconds elapsed; from any other thread (the dashboard loading a
    model beside a running engine) it runs at nice `EXPORT_NICENESS`, silently. UserError (one line) when the
    child fails."""
    waiting = threading.current_thread() is threading.main_thread()
    with tempfile.TemporaryDirectory(prefix="touchanything-export-") as scratch:
        handoff = Path(scratch) / "model.pt"
        torch.save({"config": config_to_dict(model.config), "state": model.state_dict()}, handoff)
        niceness = "0" if waiting else str(EXPORT_NICENESS)
        child = subprocess.Popen([sys.executable, "-m", __name__, str(handoff), str(folder), niceness],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        with tqdm(desc=f"exporting the ONNX graphs (first use) into {folder}", unit="s", file=sys.stderr,
                  disable=not waiting, bar_format="{desc}: {n} s") as elapsed:
            while child.poll() is None:
                time.sleep(1)
                elapsed.update(1)
        error = child.stderr.read() if child.stderr else ""
    if child.returncode != 0:
        last = (error.strip().splitlines() or [f"exit status {child.returncode}"])[-1]
        raise UserError(f"{folder}: exporting the ONNX graphs into the cache failed: {last.removeprefix(f'{folder}: ')}")


def _export_handoff(handoff: Path, folder: Path, niceness: int) -> None:
    """The child's side of `export_aside`: at `niceness` above its parent, rebuild the model from the handoff
    file and export it."""
    os.nice(niceness)
    data = torch.load(handoff, map_location="cpu", weights_only=True)
    model = create_model(config_from_dict(data["config"], str(handoff)))
    model.load_state_dict(data["state"], strict=True)
    export_onnx(model.eval(), folder, int8=True, overwrite=True)


if __name__ == "__main__":
    try:
        _export_handoff(Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]))
    except UserError as exc:
        sys.exit(str(exc))
