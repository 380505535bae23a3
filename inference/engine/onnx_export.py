"""Export the streaming engine's two graphs to ONNX (fp32, optionally int8 by dynamic quantisation).

- `encoder.onnx`: images (V, 3, S, S) float32 ImageNet-normalised, V = 1…3; view_ids (V,) int64
  → frame_tokens (N, D). Position embeddings are baked for S (no interpolation in the graph).
- `head.onnx`: frame_tokens (8, N, D), joints (P, J, 3), joint_ids (J,) int64 with J = 21 or 42,
  positions (P,) int64 → pressure (P, J // 21, 21, 21).
- `*.int8.onnx`: the same graphs with MatMul/Gemm weights quantised to int8 (ONNX Runtime dynamic
  quantisation; activations are quantised per call at run time).
- `engine.json`: the model config, input size, token count, the graph files per precision, the SHA-256 of the
  weights (`weights_sha256`, also in every graph file's metadata) and the source checkpoint
  (`touchanything.inference.engine.onnx_manifest`).

The folder is built as a whole and then takes the place of the old one, so no graph of an earlier export
(another model's int8 graphs, say) survives a new export.
"""
from __future__ import annotations

import copy
import hashlib
import io
import json
import logging
import warnings
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path

import torch

from touchanything.devices.output_safety import replacing_folder
from touchanything.inference.engine.frame_encoder import bake_position_embedding
from touchanything.inference.engine.model_halves import model_halves
from touchanything.inference.engine.onnx_manifest import MANIFEST, WEIGHTS_KEY, is_export
from touchanything.inference.engine.window_head import JOINTS_PER_HAND
from touchanything.inference.model.model_config import config_to_dict
from touchanything.inference.model.models import TactileModel

WINDOW = 8
OPSET = 18


@contextmanager
def quiet_exporter():
    """The exporter reports progress and missing optional ops (torchvision) on stdout, stderr and its loggers."""
    loggers = [logging.getLogger(name) for name in ("torch.onnx", "onnxscript")]
    levels = [logger.level for logger in loggers]
    with warnings.catch_warnings(), redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
        warnings.simplefilter("ignore")
        for logger in loggers:
            logger.setLevel(logging.ERROR)
        try:
            yield
        finally:
            for logger, level in zip(loggers, levels):
                logger.setLevel(level)


def weights_sha256(model: TactileModel) -> str:
    """The SHA-256 (hex) of the model's weights: every state-dict entry, in name order, as its name, dtype,
    shape and raw bytes. Equal for the same weights however they were loaded; any changed value changes it."""
    digest = hashlib.sha256()
    for name, tensor in sorted(model.state_dict().items()):
        tensor = tensor.detach().cpu().contiguous()
        digest.update(f"{name}|{tensor.dtype}|{tuple(tensor.shape)}|".encode())
        digest.update(tensor.reshape(-1).view(torch.uint8).numpy().tobytes())
    return digest.hexdigest()


def _export(module: torch.nn.Module, args: tuple, names: list[str], dynamic: dict, path: Path, weights: str) -> None:
    with quiet_exporter():
        program = torch.onnx.export(module, args, dynamo=True, input_names=names, output_names=[path.stem],
                                    dynamic_shapes=dynamic, opset_version=OPSET, verbose=False)
    program.model.metadata_props[WEIGHTS_KEY] = weights
    program.save(str(path))


def export_encoder(model: TactileModel, path: Path, weights: str) -> None:
    size = model.config.image_size
    views = torch.export.Dim("views", min=1, max=3)
    args = (torch.zeros(2, 3, size, size), torch.arange(2))
    _export(model_halves(model)[0].eval(), args, ["images", "view_ids"],
            {"images": {0: views}, "view_ids": {0: views}}, path, weights)


def export_head(model: TactileModel, path: Path, weights: str) -> None:
    tokens, width = model.frame_token_shape
    outputs, hands = torch.export.Dim("outputs", min=1, max=WINDOW), torch.export.Dim("hands", min=1, max=2)
    args = (torch.zeros(WINDOW, tokens, width), torch.zeros(2, 42, 3), torch.arange(42),
            torch.tensor([WINDOW - 1, 0]))
    dynamic = {"frame_tokens": None, "joints": {0: outputs, 1: JOINTS_PER_HAND * hands},
               "joint_ids": {0: JOINTS_PER_HAND * hands}, "positions": {0: outputs}}
    _export(model_halves(model)[1].eval(), args, ["frame_tokens", "joints", "joint_ids", "positions"], dynamic, path,
            weights)


def quantize_int8(source: Path, target: Path) -> None:
    """`target`: `source` with its MatMul/Gemm weights quantised to int8 (its metadata, the weights' SHA-256
    included, is kept)."""
    from onnxruntime.quantization import QuantType, quantize_dynamic

    logging.disable(logging.WARNING)  # it logs advice on the root logger for every graph
    try:
        quantize_dynamic(str(source), str(target), weight_type=QuantType.QInt8, op_types_to_quantize=["MatMul", "Gemm"])
    finally:
        logging.disable(logging.NOTSET)


def export_onnx(model: TactileModel, out_dir: Path, *, int8: bool = False, source: str = "",
                overwrite: bool = False) -> dict:
    """Write the graphs and `engine.json` (`source`: the checkpoint's path, "" when there is none) into a new
    folder that then replaces `out_dir` as a whole; return the manifest. An existing `out_dir` that is neither
    empty nor an earlier export is replaced only with `overwrite` (else UserError, nothing written)."""
    out_dir = Path(out_dir)
    weights = weights_sha256(model)
    model = copy.deepcopy(model).float().cpu().eval()
    bake_position_embedding(model)
    files = {"fp32": {"encoder": "encoder.onnx", "head": "head.onnx"}}
    if int8:
        files["int8"] = {part: f"{part}.int8.onnx" for part in ("encoder", "head")}
    manifest = {"config": config_to_dict(model.config), "image_size": model.config.image_size,
                "tokens": model.frame_token_shape[0], "width": model.frame_token_shape[1],
                "window": WINDOW, "opset": OPSET, WEIGHTS_KEY: weights, "source": source, "files": files}
    with replacing_folder(out_dir, overwrite or is_export(out_dir)) as folder:
        export_encoder(model, folder / files["fp32"]["encoder"], weights)
        export_head(model, folder / files["fp32"]["head"], weights)
        for part, name in files.get("int8", {}).items():
            quantize_int8(folder / files["fp32"][part], folder / name)
        (folder / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest
