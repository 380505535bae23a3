"""ONNX export and runtimes, bf16, numerics at the extremes, and the user errors of runtime selection."""
from __future__ import annotations

import numpy as np
import pytest

from touchanything.app.cli import main
from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.onnx_runtime import OnnxRuntime
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.checkpoint import build_model, load_model
from touchanything.inference.model.model_config import PRESETS


@pytest.fixture(scope="module")
def exported(perturbed_nano, perturbed_nano_export):
    """A nano checkpoint and its ONNX export (fp32 + int8) made by the command line."""
    return load_model(perturbed_nano).eval(), perturbed_nano_export


def stream(size: int, frames: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    for i in range(frames):
        valid = np.array([True, i % 4 != 3])
        yield Snapshot(i, i * 33_333, {v: rng.integers(0, 256, (size, size, 3), dtype=np.uint8) for v in VIEW_NAMES},
                       (rng.normal(0, 2, (42, 3)) + [0, 0, 40]).astype(np.float32), valid)


def outputs(engine: StreamingEngine, snapshots) -> np.ndarray:
    return np.stack([p.pressure for s in snapshots for p in engine.step(s)])


def test_export_writes_both_graphs_and_reports_agreement(exported, capsys):
    _, graphs = exported
    names = {p.name for p in graphs.iterdir()}
    assert {"encoder.onnx", "head.onnx", "encoder.int8.onnx", "head.int8.onnx", "engine.json"} <= names
    assert (graphs / "encoder.int8.onnx").stat().st_size < (graphs / "encoder.onnx").stat().st_size


@pytest.mark.parametrize("views", [("ego",), VIEW_NAMES])
def test_onnx_fp32_engine_equals_the_torch_engine(exported, views):
    model, graphs = exported
    reference = outputs(StreamingEngine(model, EngineSetting(views=views)), stream(112, 18))
    onnx = outputs(StreamingEngine(model, EngineSetting(runtime="onnx", views=views), onnx_dir=graphs), stream(112, 18))
    assert float(np.nanmax(np.abs(onnx - reference))) < 1e-4


@pytest.mark.parametrize("runtime,precision", [("onnx", "int8"), ("torch", "bf16")])
def test_reduced_precision_stays_close_and_finite_at_the_extremes(exported, runtime, precision):
    model, graphs = exported
    config = EngineSetting(runtime=runtime, precision=precision, invalid_hands="official")
    reference = outputs(StreamingEngine(model, EngineSetting(invalid_hands="official")), stream(112, 16))
    reduced = outputs(StreamingEngine(model, config, onnx_dir=graphs), stream(112, 16))
    assert float(np.nanmax(np.abs(reduced - reference))) < 0.1
    engine = StreamingEngine(model, config, onnx_dir=graphs)
    images = [np.zeros((112, 112, 3), np.uint8), np.full((112, 112, 3), 255, np.uint8),
              np.where(np.indices((112, 112, 3)).sum(0) % 2, 255, 0).astype(np.uint8)]
    joints = [np.full((42, 3), 1e6, np.float32), np.full((42, 3), -1e6, np.float32), np.full((42, 3), np.nan, np.float32),
              np.full((42, 3), np.inf, np.float32)]
    for i in range(12):
        frame = Snapshot(i, i, {v: images[i % 3] for v in VIEW_NAMES}, joints[i % 4], np.array([True, True]))
        (prediction,) = engine.step(frame)
        inside = prediction.pressure[~np.isnan(prediction.pressure)]
        assert inside.size and np.all((inside >= 0) & (inside <= 1))


def test_runtime_selection_errors_are_clear(exported, tmp_path, capsys):
    model, graphs = exported
    bad = [(dict(runtime="tensorrt"), "unknown runtime"), (dict(precision="int8"), "no precision"),
           (dict(output="middle"), "output position"), (dict(every=0), "whole number"), (dict(every=True), "whole number"),
           (dict(every=2, output="centre"), "newest"), (dict(views=("wrist_left",)), "must include ego"),
           (dict(invalid_hands="zero"), "invalid-hand mode")]
    for knobs, message in bad:  # refused when the setting is made, before any engine
        with pytest.raises(UserError, match=message):
            EngineSetting(**knobs)
    with pytest.raises(UserError, match="fp16 needs a CUDA GPU"):  # a device it cannot run on: when the engine is built
        StreamingEngine(model, EngineSetting(precision="fp16", device="cpu"))
    with pytest.raises(UserError, match="export-onnx"):
        StreamingEngine(model, EngineSetting(runtime="onnx"), onnx_dir=tmp_path)
    other = build_model(PRESETS["tiny"])
    with pytest.raises(UserError, match="different model"):
        StreamingEngine(other, EngineSetting(runtime="onnx"), onnx_dir=graphs)
    (tmp_path / "engine.json").write_text('{"files": {"fp32": {"encoder": "x.onnx", "head": "y.onnx"}}, "image_size": 112}')
    with pytest.raises(UserError, match="cannot open the ONNX graphs"):
        OnnxRuntime(tmp_path)
    assert main(["export-onnx", "--checkpoint", str(tmp_path / "missing.pth"), "--out", str(tmp_path / "o")]) == 2
    assert "missing.pth" in capsys.readouterr().err
