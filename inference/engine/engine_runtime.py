"""Runtimes for the streaming engine's two halves: torch here (fp32, bf16; fp16/bf16 on GPU) and ONNX
Runtime (`touchanything.inference.engine.onnx_runtime`: fp32, int8). All satisfy `Runtime`, so selecting a
runtime never changes the engine; `make_runtime` builds the one an `EngineSetting` selects.
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch

from touchanything.inference.engine.captured_call import CapturedCalls
from touchanything.inference.engine.engine_setting import EngineSetting, compute_threads
from touchanything.inference.engine.model_halves import model_halves
from touchanything.inference.engine.onnx_runtime import OnnxRuntime, onnx_folder
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.preprocess import model_input, model_input_on_device
from touchanything.inference.model.torch_device import autocast


class Runtime(Protocol):
    """The streaming engine's view of a runtime. Frame tokens are opaque to the engine: what `encode`
    returns (a torch tensor, a numpy array) is cached and handed back to `head`.

    `prepare(frames [V of (H, W, 3) uint8 RGB], size) -> model input` (on the runtime's device);
    `encode(model input (V, 3, S, S) float32, view_ids (V,) int64) -> frame tokens`;
    `head(frame_tokens [T of them], joints (P, J, 3), joint_ids (J,), positions (P,)) -> (P, J // 21, 21, 21)`
    float32 numpy in [0, 1] (the one device-to-host copy of a prediction).
    `device` is where it runs; `capture` says whether its calls are captured ("CUDA graphs") or why not."""

    name: str
    precision: str
    device: torch.device
    capture: str

    def prepare(self, frames: list[np.ndarray], size: int) -> Any: ...

    def encode(self, images: Any, view_ids: np.ndarray) -> Any: ...

    def head(self, frame_tokens: list[Any], joints: np.ndarray, joint_ids: np.ndarray,
             positions: np.ndarray) -> np.ndarray: ...


class TorchRuntime:
    """The model's own modules under torch on any device; bf16/fp16 through autocast, results as float32.

    On a CUDA GPU frames are uploaded as uint8 and resized and normalised there (`model_input_on_device`),
    and the encoder (per view count) and the window head (per window length and hand set) are captured as
    CUDA graphs (`CapturedCalls`); on the CPU the frames are prepared with cv2 and the same calls run
    eagerly. `capture` says which."""

    def __init__(self, model: TactileModel, precision: str = "fp32", device: str = "auto", threads: int | None = None,
                 capture: bool = True) -> None:
        """`threads` sets torch's intra-op thread count, which is process-wide (None: leave it); `capture`
        False runs a GPU eagerly too."""
        self.device = EngineSetting(runtime="torch", precision=precision, device=device).resolved_device()
        if threads is not None:
            torch.set_num_threads(threads)
        self.name, self.precision = "torch", precision
        model = model.to(self.device).eval()
        encoder, window_head = model_halves(model)
        self._encode = CapturedCalls(encoder, self._context, capture)
        self._head = CapturedCalls(window_head, self._context, capture)

    @contextmanager
    def _context(self) -> Iterator[None]:
        """Every call of the model's modules: no autograd, autocast at the runtime's precision."""
        with torch.no_grad(), autocast(self.device, self.precision):
            yield

    @property
    def capture(self) -> str:
        modes = {self._encode.mode, self._head.mode} - {"not run yet"}
        return "; ".join(sorted(modes)) or self._encode.expected_mode(self.device)

    def prepare(self, frames: list[np.ndarray], size: int) -> np.ndarray | torch.Tensor:
        if self.device.type == "cuda":
            return model_input_on_device(frames, size, self.device)
        return model_input(frames, size)

    def encode(self, images: np.ndarray | torch.Tensor, view_ids: np.ndarray) -> torch.Tensor:
        images = torch.as_tensor(images).to(self.device, torch.float32)
        return self._encode(images, torch.from_numpy(view_ids).to(self.device)).float()

    def head(self, frame_tokens: list[torch.Tensor], joints: np.ndarray, joint_ids: np.ndarray,
             positions: np.ndarray) -> np.ndarray:
        tensors = [torch.from_numpy(a).to(self.device) for a in (joints, joint_ids, positions)]
        return self._head(torch.stack(frame_tokens), *tensors).float().cpu().numpy()


def make_runtime(model: TactileModel, setting: EngineSetting, onnx_dir: Path | None = None,
                 threads: int | None = None) -> Runtime:
    """The runtime `setting` selects for `model` (its device checked first) with `threads` CPU threads (None:
    `compute_threads()`). ONNX runs the graphs of the export folder `onnx_dir`, else those cached for this
    model, exporting them on first use (`onnx_runtime.onnx_folder`)."""
    setting.resolved_device()
    threads = threads or compute_threads()
    if setting.runtime == "torch":
        return TorchRuntime(model, setting.precision, setting.device, threads, setting.capture)
    return OnnxRuntime(onnx_folder(model, onnx_dir, setting.precision), setting.precision, threads)
