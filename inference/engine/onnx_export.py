"""Export the streaming engine's two graphs to ONNX (fp32, optionally int8 by dynamic quantisation).

- `encoder.onnx`: images (V, 3, S, S) float32 ImageNet-normalised, V = 1…3; view_ids (V,) int64
  → frame_tokens (N, D). Position embeddings are baked for S (no interpolation in the graph).
- `head.onnx`: frame_tokens (8, N, D), joints (P, J, 3), joint_ids (J,) int64 with J = 21 or 42,
  positions (P,) int64 → pressure (P, J // 21, 21, 21).
- `*.int8.onnx`: the same graphs with MatMul/Gemm weights quantised to int8 (ONNX Runtime dynamic
  quantisation; activations are quantised per call at run time).
- `engine.json`: the model config, input size, token count and the graph files per precision (read back by
  `read_manifest`).
"""
from __future__ import annotations

import copy
import io
import json
import logging
import warnings
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from pathlib import Path

import torch

from touchanything.devices.errors import UserError
from touchanything.devices.output_safety import replacing, write_text
from touchanything.inference.engine.frame_encoder import bake_position_embedding
from touchanything.inference.engine.model_halves import model_halves
from touchanything.inference.engine.window_head import JOINTS_PER_HAND
from touchanything.inference.model.model_config import config_to_dict
from touchanything.inference.model.models import TactileModel

WINDOW = 8
OPSET = 18
MANIFEST = "engine.json"


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


def _export(module: torch.nn.Module, args: tuple, names: list[str], dynamic: dict, path: Path) -> None:
    with quiet_exporter():
        program = torch.onnx.export(module, args, dynamo=True, input_names=names, output_names=[path.stem],
                                    dynamic_shapes=dynamic, opset_version=OPSET, verbose=False)
    program.save(str(path))


def export_encoder(model: TactileModel, path: Path) -> None:
    size = model.config.image_size
    views = torch.export.Dim("views", min=1, max=3)
    args = (torch.zeros(2, 3, size, size), torch.arange(2))
    _export(model_halves(model)[0].eval(), args, ["images", "view_ids"],
            {"images": {0: views}, "view_ids": {0: views}}, path)


def export_head(model: TactileModel, path: Path) -> None:
    tokens, width = model.frame_token_shape
    outputs, hands = torch.export.Dim("outputs", min=1, max=WINDOW), torch.export.Dim("hands", min=1, max=2)
    args = (torch.zeros(WINDOW, tokens, width), torch.zeros(2, 42, 3), torch.arange(42),
            torch.tensor([WINDOW - 1, 0]))
    dynamic = {"frame_tokens": None, "joints": {0: outputs, 1: JOINTS_PER_HAND * hands},
               "joint_ids": {0: JOINTS_PER_HAND * hands}, "positions": {0: outputs}}
    _export(model_halves(model)[1].eval(), args, ["frame_tokens", "joints", "joint_ids", "positions"], dynamic, path)


def quantize_int8(source: Path, target: Path) -> None:
    from onnxruntime.quantization import QuantType, quantize_dynamic

    logging.disable(logging.WARNING)  # it logs advice on the root logger for every graph
    try:
        quantize_dynamic(str(source), str(target), weight_type=QuantType.QInt8, op_types_to_quantize=["MatMul", "Gemm"])
    finally:
        logging.disable(logging.NOTSET)


def export_onnx(model: TactileModel, out_dir: Path, *, int8: bool = False, source: str = "") -> dict:
    """Write the graphs and `engine.json` into `out_dir`; return the manifest."""
    out_dir = Path(out_dir)
    model = copy.deepcopy(model).float().cpu().eval()
    bake_position_embedding(model)
    files = {"fp32": {"encoder": "encoder.onnx", "head": "head.onnx"}}
    for name, export in (("encoder.onnx", export_encoder), ("head.onnx", export_head)):
        with replacing(out_dir / name) as temporary:
            export(model, temporary)
    if int8:
        files["int8"] = {part: f"{part}.int8.onnx" for part in ("encoder", "head")}
        for part in ("encoder", "head"):
            with replacing(out_dir / files["int8"][part]) as temporary:
                quantize_int8(out_dir / files["fp32"][part], temporary)
    manifest = {"config": config_to_dict(model.config), "image_size": model.config.image_size,
                "tokens": model.frame_token_shape[0], "width": model.frame_token_shape[1],
                "window": WINDOW, "opset": OPSET, "source": source, "files": files}
    write_text(out_dir / MANIFEST, json.dumps(manifest, indent=2) + "\n")
    return manifest


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
