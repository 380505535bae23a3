"""The ONNX Runtime runtime: the two graphs written by `touchanything.inference.engine.onnx_export`, run on
the CPU execution provider, and the folder they come from (a user's export, checked against the model's
architecture and weights, or the per-model cache that is filled on first use)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from touchanything.core.errors import UserError
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.onnx_cache import export_aside, onnx_cache_dir
from touchanything.inference.engine.onnx_export import weights_sha256
from touchanything.inference.engine.onnx_manifest import REEXPORT, WEIGHTS_KEY, check_weights, export_weights, read_manifest
from touchanything.inference.model.model_config import config_to_dict
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.preprocess import model_input


class OnnxRuntime:
    """The exported encoder and head graphs at one precision (satisfies `engine_runtime.Runtime`). Each graph
    file must carry the weights' SHA-256 its manifest records (UserError otherwise: a graph of another export)."""

    def __init__(self, folder: Path, precision: str = "fp32", threads: int | None = None) -> None:
        import onnxruntime as ort

        self.device = EngineSetting(runtime="onnx", precision=precision, device="cpu").resolved_device()
        self.name, self.precision, self.capture = "onnx", precision, "n/a (ONNX Runtime session)"
        manifest = read_manifest(folder)
        files = manifest["files"][precision]
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
        weights = export_weights(folder, manifest)
        for part, session in (("encoder", self._encoder), ("head", self._head)):
            if session.get_modelmeta().custom_metadata_map.get(WEIGHTS_KEY) != weights:
                raise UserError(f"{Path(folder) / files[part]}: this graph was not exported with the weights {folder}'s "
                                f"engine.json names (sha256 {weights[:12]}…); {REEXPORT}")

    def prepare(self, frames: list[np.ndarray], size: int) -> np.ndarray:
        return model_input(frames, size)

    def encode(self, images: np.ndarray, view_ids: np.ndarray) -> np.ndarray:
        return self._encoder.run(None, {"images": images, "view_ids": view_ids})[0]

    def head(self, frame_tokens: list[np.ndarray], joints: np.ndarray, joint_ids: np.ndarray,
             positions: np.ndarray) -> np.ndarray:
        feed = {"frame_tokens": np.stack(frame_tokens), "joints": joints, "joint_ids": joint_ids, "positions": positions}
        return self._head.run(None, feed)[0]


def check_export(model: TactileModel, weights: str, folder: Path, precision: str) -> None:
    """UserError (one line) unless `folder` holds graphs at `precision` exported from `model`: the same
    architecture (config) and the same weights (`weights`: their SHA-256, `weights_sha256(model)`)."""
    manifest = read_manifest(folder)
    if manifest["config"] != config_to_dict(model.config):
        raise UserError(f"{folder}: the ONNX graphs were exported from a different model architecture; {REEXPORT}")
    check_weights(folder, manifest, weights)
    if precision not in manifest["files"]:
        raise UserError(f"{folder}: no {precision} graphs; export with `touchanything export-onnx --int8`")


def onnx_folder(model: TactileModel, folder: Path | None, precision: str) -> Path:
    """The folder holding graphs for `model` at `precision`: `folder` when given (checked against the model,
    `check_export`), else the user cache, (re-)exported there first, fp32 and int8 (`onnx_cache.export_aside`:
    in a child process, so that a running engine keeps its pace), when it does not hold this model's graphs at
    `precision`."""
    weights = weights_sha256(model)
    if folder is not None:
        check_export(model, weights, folder, precision)
        return folder
    folder = onnx_cache_dir(weights)
    try:
        check_export(model, weights, folder, precision)
    except UserError:
        export_aside(model, folder)
        check_export(model, weights, folder, precision)
    return folder
