"""Runtimes for the streaming engine's two halves: torch (fp32, bf16; fp16/bf16 on GPU) and ONNX Runtime
(fp32, int8). All share one interface, so selecting a runtime never changes the engine.

`encode(images (V, 3, S, S) float32, view_ids (V,) int64) -> frame tokens` (opaque, cached by the engine);
`head(frame_tokens [T of them], joints (P, J, 3), joint_ids (J,), positions (P,)) -> (P, J // 21, 21, 21)`
float32 numpy in [0, 1].
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from touchanything.devices.errors import UserError
from touchanything.inference.engine.frame_encoder import FrameEncoder
from touchanything.inference.engine.window_head import WindowHead
from touchanything.inference.model.touch_model import TouchAnything

RUNTIMES = {"torch": ("fp32", "bf16", "fp16"), "onnx": ("fp32", "int8")}
MANIFEST = "engine.json"


def check_runtime(runtime: str, precision: str, device: str = "cpu") -> None:
    """Raise UserError for an unknown runtime / precision pair or one the device cannot run."""
    if runtime not in RUNTIMES:
        raise UserError(f"unknown runtime {runtime!r}; choose from {', '.join(RUNTIMES)}")
    if precision not in RUNTIMES[runtime]:
        raise UserError(f"runtime {runtime} has no precision {precision!r}; choose from {', '.join(RUNTIMES[runtime])}")
    if precision == "fp16" and device == "cpu":
        raise UserError("fp16 needs a GPU (--device cuda); on CPU use bf16")
    if device != "cpu" and not torch.cuda.is_available():
        raise UserError(f"device {device!r} is not available (no CUDA GPU); use --device cpu")


class TorchRuntime:
    """The model's own modules under torch; bf16/fp16 through autocast, results returned as float32."""

    def __init__(self, model: TouchAnything, precision: str = "fp32", device: str = "cpu", threads: int | None = None) -> None:
        """`threads` sets torch's intra-op thread count, which is process-wide (None: leave it)."""
        check_runtime("torch", precision, device)
        if threads is not None:
            torch.set_num_threads(threads)
        self.name, self.precision, self.device = "torch", precision, torch.device(device)
        model = model.to(self.device).eval()
        self.encoder, self.window_head = FrameEncoder(model), WindowHead(model)
        self._dtype = {"fp32": None, "bf16": torch.bfloat16, "fp16": torch.float16}[precision]

    def _autocast(self):
        return torch.autocast(self.device.type, dtype=self._dtype, enabled=self._dtype is not None)

    @torch.inference_mode()
    def encode(self, images: np.ndarray, view_ids: np.ndarray) -> torch.Tensor:
        with self._autocast():
            tokens = self.encoder(torch.from_numpy(images).to(self.device), torch.from_numpy(view_ids).to(self.device))
        return tokens.float()

    @torch.inference_mode()
    def head(self, frame_tokens: list[torch.Tensor], joints: np.ndarray, joint_ids: np.ndarray,
             positions: np.ndarray) -> np.ndarray:
        tensors = [torch.from_numpy(a).to(self.device) for a in (joints, joint_ids, positions)]
        with self._autocast():
            out = self.window_head(torch.stack(frame_tokens), *tensors)
        return out.float().cpu().numpy()


class OnnxRuntime:
    """The two graphs written by `touchanything.inference.engine.onnx_export` under ONNX Runtime (CPU execution provider)."""

    def __init__(self, folder: Path, precision: str = "fp32", threads: int | None = None) -> None:
        import onnxruntime as ort

        check_runtime("onnx", precision)
        self.name, self.precision = "onnx", precision
        self.manifest = read_manifest(folder)
        files = self.manifest["files"][precision]
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

    def encode(self, images: np.ndarray, view_ids: np.ndarray) -> np.ndarray:
        return self._encoder.run(None, {"images": images, "view_ids": view_ids})[0]

    def head(self, frame_tokens: list[np.ndarray], joints: np.ndarray, joint_ids: np.ndarray,
             positions: np.ndarray) -> np.ndarray:
        feed = {"frame_tokens": np.stack(frame_tokens), "joints": joints, "joint_ids": joint_ids, "positions": positions}
        return self._head.run(None, feed)[0]


def read_manifest(folder: Path) -> dict:
    """The export's engine.json (config, input size, graph files per precision)."""
    path = Path(folder) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
        manifest["files"], manifest["image_size"]
    except FileNotFoundError:
        raise UserError(f"{folder}: no {MANIFEST}; create the folder with `touchanything export-onnx`") from None
    except (OSError, ValueError, KeyError, TypeError):
        raise UserError(f"{path}: not a valid ONNX export manifest") from None
    return manifest
