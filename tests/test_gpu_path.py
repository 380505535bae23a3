"""The GPU code path, run where CI can run it: device parsing and errors, on-device preprocessing against cv2,
captured calls falling back to eager on the CPU with identical outputs."""
from __future__ import annotations

import runpy
from pathlib import Path

import numpy as np
import pytest
import torch
from torch.overrides import TorchFunctionMode

from touchanything.app.cli import main
from touchanything.app.sessions.bundled import SAMPLE_DIR, bundled_models
from touchanything.app.sessions.scene import read_scene
from touchanything.devices.errors import UserError
from touchanything.devices.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine import captured_call
from touchanything.inference.engine.captured_call import CapturedCall, CapturedCalls
from touchanything.inference.engine.engine_config import EngineConfig, check_runtime
from touchanything.inference.engine.engine_runtime import TorchRuntime
from touchanything.inference.engine.model_halves import model_halves
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.checkpoint import load_model
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.preprocess import IMAGENET_STD, model_input, model_input_on_device
from touchanything.inference.model.torch_device import check_precision, device_label, resolve_device
from touchanything.inference.model.touch_model import TouchAnything

TOLERANCE = 1e-4
pytestmark = pytest.mark.skipif(torch.cuda.is_available(), reason="checks the CPU fallbacks of a machine without CUDA")


def test_auto_chooses_the_cpu_here_and_names_are_checked():
    assert resolve_device("auto") == torch.device("cpu") and resolve_device("cpu") == torch.device("cpu")
    assert device_label(torch.device("cpu")) == "cpu"
    for name, message in (("cuda", "no usable CUDA GPU"), ("cuda:1", "no usable CUDA GPU"), ("gpu", "unknown device"),
                          ("cuda:x", "unknown device"), ("", "unknown device"), (0, "device must be text")):
        with pytest.raises(UserError, match=message):
            resolve_device(name)


def test_precision_and_runtime_device_pairs():
    with pytest.raises(UserError, match="fp16 needs a CUDA GPU"):
        check_precision("fp16", torch.device("cpu"))
    with pytest.raises(UserError, match="unknown precision"):
        check_precision("fp8", torch.device("cpu"))
    assert check_runtime("onnx", "int8", "auto") == torch.device("cpu")  # ONNX Runtime is the CPU build
    with pytest.raises(UserError, match="no usable CUDA GPU"):
        check_runtime("onnx", "fp32", "cuda")
    with pytest.raises(UserError, match="unknown device"):
        check_runtime("onnx", "fp32", "tpu")


@pytest.mark.parametrize("height, width, size", [(480, 640, 224), (48, 64, 112), (224, 224, 224), (1, 1, 14)])
def test_on_device_preprocessing_agrees_with_cv2_within_one_intensity(height, width, size):
    rng = np.random.default_rng(height)
    frames = [rng.integers(0, 256, (height, width, 3), np.uint8) for _ in VIEW_NAMES]
    frames[1][:] = 255  # saturated
    frames[2][:] = 0  # black
    on_cpu = model_input(frames, size)
    on_device = model_input_on_device(frames, size, torch.device("cpu")).numpy()
    assert on_device.shape == on_cpu.shape == (3, 3, size, size) and on_device.dtype == np.float32
    intensity = np.abs(on_device - on_cpu) * IMAGENET_STD.numpy()[None] * 255
    assert intensity.max() <= 1.0 + 1e-3
    assert np.array_equal(on_device[1:], on_cpu[1:])  # flat frames resize exactly
    if (height, width) == (size, size):
        assert np.array_equal(on_device, on_cpu)


def test_a_captured_call_runs_eagerly_on_the_cpu_with_identical_outputs():
    weight = torch.randn(8, 4)
    calls = CapturedCalls(lambda x: torch.tanh(x @ weight.T), lambda: torch.no_grad())
    assert calls.mode == "not run yet"
    for rows in (3, 5, 3):
        x = torch.randn(rows, 4)
        assert torch.equal(calls(x), torch.tanh(x @ weight.T))
    assert len(calls.calls) == 2 and calls.mode == "eager (CUDA graphs need a CUDA GPU)"
    single = CapturedCall(lambda x: x * 2, [torch.zeros(2)], lambda: torch.no_grad())
    first = single(torch.ones(2))
    single(torch.full((2,), 5.0))
    assert torch.equal(first, torch.full((2,), 2.0))  # outputs are not overwritten by the next call


def test_beyond_the_graph_limit_calls_run_eagerly(monkeypatch):
    monkeypatch.setattr(captured_call, "MAX_GRAPHS", 2)
    calls = CapturedCalls(lambda x: x + 1, lambda: torch.no_grad())
    for rows in (1, 2, 3, 4):
        assert torch.equal(calls(torch.zeros(rows)), torch.ones(rows))
    assert len(calls.calls) == 2 and calls.eager_beyond_limit == 2


class HostData(TorchFunctionMode):
    """Records the calls that move data between the host and tensors. Inside a CUDA-graph capture a tensor made
    from Python data is a CPU→GPU copy, which fails the capture (the new nano's decoder did, on an H200), and
    `item`/`cpu` read the GPU back."""
    NAMES = {"tensor", "as_tensor", "item", "tolist", "cpu", "numpy"}

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[str] = []

    def __torch_function__(self, func, types, args=(), kwargs=None):
        if getattr(func, "__name__", "") in self.NAMES:
            self.seen.append(func.__name__)
        return func(*args, **(kwargs or {}))


@pytest.mark.parametrize("name", ["nano", "tiny", "small", "pico", "bundled nano", "bundled baseline_frames", "bundled pico"])
def test_the_captured_halves_make_no_tensor_from_host_data(name):
    torch.manual_seed(0)
    model = load_model(bundled_models()[name.split()[1]]) if name.startswith("bundled") else TouchAnything(preset(name))
    encoder, head = model_halves(model.eval())
    size, (tokens, width) = model.config.image_size, model.frame_token_shape
    with torch.no_grad(), HostData() as host:
        encoded = encoder(torch.rand(3, 3, size, size), torch.arange(3))
        maps = head(torch.rand(8, tokens, width), torch.rand(2, 42, 3), torch.arange(42), torch.arange(2) * 7)
    assert encoded.shape == (tokens, width) and maps.shape[:2] == (2, 2)
    assert host.seen == [], host.seen


def clip(count: int = 20) -> list[Snapshot]:
    rng = np.random.default_rng(3)
    joints = rng.uniform(-3, 3, (42, 3)).astype(np.float32)
    joints[:, 2] += 50
    return [Snapshot(i, i * 33_333, {v: rng.integers(0, 256, (48, 64, 3), np.uint8) for v in VIEW_NAMES}, joints,
                     np.ones(2, bool)) for i in range(count)]


def test_the_engine_reports_its_device_and_eager_mode_and_on_device_preprocessing_stays_close():
    torch.manual_seed(0)
    model = TouchAnything(preset("nano")).eval()
    engine = StreamingEngine(model, EngineConfig(device="auto"))
    runtime = engine.runtime
    assert isinstance(runtime, TorchRuntime) and runtime.device == torch.device("cpu")
    outputs = [p.pressure for s in clip() for p in engine.step(s)]
    assert runtime.capture == "eager (CUDA graphs need a CUDA GPU)"
    # the GPU's preprocessing on the same frames: within the measured bound of the cv2 path's predictions
    runtime.prepare = lambda frames, size: model_input_on_device(frames, size, runtime.device)
    engine.reset()
    shifted = [p.pressure for s in clip() for p in engine.step(s)]
    difference = np.nanmax(np.abs(np.array(outputs) - np.array(shifted)))
    assert difference < 0.02


@pytest.mark.parametrize("argv, message", [
    (["replay", "EPISODE", "--headless", "--device", "cuda"], "no usable CUDA GPU"),
    (["demo", "--headless", "--device", "cuda:0"], "no usable CUDA GPU"),
    (["replay", "EPISODE", "--headless", "--precision", "fp16", "--device", "cpu"], "fp16 needs a CUDA GPU"),
    (["replay", "EPISODE", "--headless", "--runtime", "onnx", "--device", "cuda"], "no usable CUDA GPU"),
    (["eval", "--checkpoint", "CKPT", "--data", "DATA", "--device", "cuda"], "no usable CUDA GPU"),
    (["eval", "--checkpoint", "CKPT", "--data", "DATA", "--precision", "fp16", "--device", "cpu"], "fp16 needs a CUDA GPU"),
])
def test_every_command_names_a_device_it_cannot_use_in_one_line(argv, message, episode_dir, sim_hdf5_root,
                                                                tiny_checkpoint, capsys):
    scene = Path(__file__).resolve().parents[1] / "scenes" / "sim.toml"
    values = {"EPISODE": str(episode_dir), "SCENE": str(scene), "CKPT": str(tiny_checkpoint), "DATA": str(sim_hdf5_root)}
    assert main([values.get(a, a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_live_keeps_the_rig_running_and_says_why_the_device_cannot_predict(capsys):
    scene = Path(__file__).resolve().parents[1] / "scenes" / "sim.toml"
    assert main(["live", "--scene", str(scene), "--headless", "--seconds", "1", "--device", "cuda"]) == 0
    captured = capsys.readouterr()
    assert "no prediction: device 'cuda' asked for, but this machine has no usable CUDA GPU" in captured.out
    assert captured.err == "" and "model     no model" in captured.out


def test_a_scene_names_the_device_of_its_model(tmp_path, capsys):
    scene = (Path(__file__).resolve().parents[1] / "scenes" / "sim.toml").read_text().replace("../recordings", str(
        Path(__file__).resolve().parents[1] / "recordings"))
    (tmp_path / "cpu.toml").write_text(scene.replace('device = "auto"', 'device = "cpu"'))
    (tmp_path / "gpu.toml").write_text(scene.replace('device = "auto"', 'device = "cuda:0"'))
    assert read_scene(tmp_path / "cpu.toml").model.device == "cpu"
    assert main(["live", "--scene", str(tmp_path / "gpu.toml"), "--headless", "--seconds", "0.5"]) == 0
    assert "no prediction: device 'cuda:0' asked for" in capsys.readouterr().out


def test_the_exactness_benchmark_measures_the_bundled_nano_on_the_cpu():
    """benchmarks/gpu_exactness.py (whose GPU figures docs/engine.md reports), on the CPU: the streamed newest
    frame equals the batch forward, eager equals itself, bf16 stays close, fp16 and tf32 are left out."""
    bench = runpy.run_path(str(Path(__file__).resolve().parents[1] / "benchmarks" / "gpu_exactness.py"))
    clip = bench["first_latency_clip"]([bench["episode_paths"](SAMPLE_DIR)[0]], 18)
    row = bench["measure"](load_model(bundled_models()["nano"]), clip, torch.device("cpu"))
    assert row["capture"] == "eager (CUDA graphs need a CUDA GPU)"
    assert row["fp32 vs batch"] < TOLERANCE and row["eager vs graphs"] == 0.0
    assert "fp16 vs fp32" not in row and "tf32 vs fp32" not in row and 0.0 <= row["bf16 vs fp32"]["max"] < 0.05
    assert 0.0 <= row["bf16 vs fp32"]["contact agreement"] <= 1.0
    assert row["preprocessing levels"] <= 1.0 + 1e-3
    table = bench["markdown"]({"machine": "m", "device": "cpu", "episode": "e", "frames": 18, "models": {"nano": row}})
    assert "| nano | eager (CUDA graphs need a CUDA GPU) |" in table and "| n/a |" in table


def test_tf32_is_a_gpu_precision_set_only_inside_its_context():
    """tf32 (fp32 weights, TensorFloat-32 matrix products on a GPU): refused on the CPU; its context sets CUDA's
    matmul and convolution mode and restores it after, also after an error; on the CPU it computes fp32 exactly;
    the GPU bench measures it beside fp32."""
    from touchanything.inference.evaluation.bench_gpu import gpu_settings
    from touchanything.inference.model.torch_device import autocast

    with pytest.raises(UserError, match="tf32 needs a CUDA GPU"):
        check_precision("tf32", torch.device("cpu"))
    with pytest.raises(UserError, match="tf32 needs a CUDA GPU"):
        check_runtime("torch", "tf32", "cpu")
    modes = (torch.backends.cuda.matmul, torch.backends.cudnn.conv)
    before = [m.fp32_precision for m in modes]
    assert before != ["tf32", "tf32"]
    with autocast(torch.device("cpu"), "tf32"):
        assert [m.fp32_precision for m in modes] == ["tf32", "tf32"]
    assert [m.fp32_precision for m in modes] == before
    with pytest.raises(ZeroDivisionError), autocast(torch.device("cpu"), "tf32"):
        raise ZeroDivisionError
    assert [m.fp32_precision for m in modes] == before
    with autocast(torch.device("cpu"), "fp32"):
        assert [m.fp32_precision for m in modes] == before  # fp32 leaves the mode alone
    torch.manual_seed(0)
    model = TouchAnything(preset("nano")).eval()
    encoder, _ = model_halves(model)
    images, ids = torch.rand(3, 3, 96, 96), torch.arange(3)
    with torch.no_grad():
        plain = encoder(images, ids)
        with autocast(torch.device("cpu"), "tf32"):
            assert torch.equal(encoder(images, ids), plain)
    assert "tf32" in {s.precision for s in gpu_settings("paper", torch.device("cuda"))}
    assert "tf32" not in {s.precision for s in gpu_settings("paper", torch.device("cpu"))}
