"""The ONNX Runtime runtime: the two graphs written by `touchanything.inference.engine.onnx_export`, run on
the CPU execution provider, and the folder they come from (a user's export, or the per-model cache that is
filled on first use)."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from touchanything.devices.errors import UserError
from touchanything.inference.engine.engine_config import check_runtime
from touchanything.inference.engine.onnx_export import MANIFEST, export_onnx, read_manifest
from touchanything.inference.model.model_config import config_to_dict
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.preprocess import model_input


class OnnxRuntime:
    """The exported encoder and head graphs at one precision (satisfies `engine_runtime.Runtime`)."""

    def __init__(self, folder: Path, precision: str = "fp32", threads: int | None = None) -> None:
        import onnxruntime as ort

        self.device = check_runtime("onnx", precision, "cpu")
        self.name, self.precision, self.capture = "onnx", precision, "n/a (ONNX Runtime session)"
        files = read_manifest(folder)["files"][precision]
        options = ort.SessionOptions()
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        options.log_severity_level = 3
        options.intra_op_num_threads = threads or 0
        # Spinning worker threads would steal the cores from preprocessing and the other graph between calls.
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
        try:
            self._encoder, self._head = (ort.InferenceSession(str(Path(folder) / files[part]), options,
                                                              providers=["CPUExecutionProvider"])
                                         for part in ("encoder", "head"))
        except Exception as exc:  # onnxruntime raises its own exception types for unreadable graphs
            raise UserError(f"{folder}: cannot open the ONNX graphs ({str(exc).splitlines()[0]})") from None

    def prepare(self, frames: list[np.ndarray], size: int) -> np.ndarray:
        return model_input(frames, size)

    def encode(self, images: np.ndarray, view_ids: np.ndarray) -> np.ndarray:
        return self._encoder.run(None, {"images": images, "view_ids": view_ids})[0]

    def head(self, frame_tokens: list[np.ndarray], joints: np.ndarray, joint_ids: np.ndarray,
             positions: np.ndarray) -> np.ndarray:
        feed = {"frame_tokens": np.stack(frame_tokens), "joints": joints, "joint_ids": joint_ids, "positions": positions}
        return self._head.run(None, feed)[0]


def model_digest(model: TactileModel) -> str:
    """A short hash of the model's weights and config (names the cached ONNX export)."""
    digest = hashlib.sha256(repr(config_to_dict(model.config)).encode())
    for name, tensor in sorted(model.state_dict().items()):
        digest.update(name.encode())
        digest.update(tensor.detach().float().cpu().numpy().tobytes())
    return digest.hexdigest()[:16]


def onnx_cache_dir(model: TactileModel) -> Path:
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return root / "touchanything" / "onnx" / model_digest(model)


def onnx_folder(model: TactileModel, folder: Path | None, precision: str) -> Path:
    """The folder holding graphs for `model` at `precision`: `folder` when given (checked against the model),
    else the user cache, exported there first when missing."""
    if folder is None:
        folder = onnx_cache_dir(model)
        has = (folder / MANIFEST).is_file() and precision in read_manifest(folder)["files"]
        if not has:
            export_onnx(model, folder, int8=True, source="cache")
        return folder
    manifest = read_manifest(folder)
    if manifest["config"] != config_to_dict(model.config):
        raise UserError(f"{folder}: the ONNX graphs were exported from a different model architecture")
    if precision not in manifest["files"]:
        raise UserError(f"{folder}: no {precision} graphs; export with `touchanything export-onnx --int8`")
    return folder
