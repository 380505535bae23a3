"""The GPU code path on the machine at hand: device names and errors, on-device preprocessing against cv2, the
captured calls, the engine's device, capture and precisions, and the exactness benchmark.

The tests of the path take the `device` fixture: the CPU everywhere (the fallbacks: cv2 preprocessing, eager
calls, fp32 and bf16), and the first CUDA GPU where there is one (CUDA graphs, on-device preprocessing, fp16 and
tf32 too), each with that device's expectations. Tests of what a machine without CUDA says skip where there is
one; tests of what only a GPU does skip where there is none. The GPU bounds are those of the H100/H200 runs of
benchmarks/gpu_exactness.py (docs/engine.md "The GPU path", docs/bench/gpu_exactness.md), with a margin where
the docs give a measurement rather than a bound."""
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
from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine import captured_call
from touchanything.inference.engine.captured_call import CapturedCall, CapturedCalls
from touchanything.inference.engine.engine_runtime import TorchRuntime
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.model_halves import model_halves
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.checkpoint import load_model
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.preprocess import IMAGENET_STD, model_input, model_input_on_device
from touchanything.inference.model.torch_device import PRECISIONS, check_precision, device_label, resolve_device
from touchanything.inference.model.touch_model import TouchAnything

TOLERANCE = 1e-4
"""The newest frame against the batch forward of the same clip, fp32, on either device (docs/engine.md)."""
CUDA = torch.cuda.is_available()
without_cuda = pytest.mark.skipif(CUDA, reason="what a machine without a CUDA GPU says: this one has one")
with_cuda = pytest.mark.skipif(not CUDA, reason="what only a CUDA GPU does: this machine has none")

CAPTURED = {"cpu": "eager (CUDA graphs need a CUDA GPU)", "cuda": "CUDA graphs"}
"""A runtime's calls after they ran, per device type."""
CAPTURE_OFF = {"cpu": "eager (CUDA graphs need a CUDA GPU)", "cuda": "eager (capture off)"}
GRAPHS_VS_EAGER = {"cpu": 0.0, "cuda": 1e-6}
"""Max |captured − eager|: the same eager calls on the CPU; on a GPU measured 6e-8 or less (0 for nano)."""
LOW_PRECISION_MAX = {"cpu": {"bf16": 0.05}, "cuda": {"bf16": 0.01, "fp16": 0.002, "tf32": 0.01}}
"""Max |precision − fp32| of the newest-frame pressure. GPU, measured: bf16 0.0014–0.0034, fp16 0.0002–0.0003
(tf32 not yet measured: TF32 keeps more mantissa bits than bf16, so bf16's bound)."""
BENCH_FRAMES = {"cpu": 18, "cuda": 60}
"""Frames of the exactness bench: on a GPU, the 60 of the documented run."""
INTENSITY = 1.0 + 1e-3
"""Max |on-device − cv2| model input in intensity levels (1/255): cv2's 11-bit fixed-point weights."""


@pytest.fixture(params=["cpu", "cuda:0"] if CUDA else ["cpu"])
def device(request) -> torch.device:
    return torch.device(request.param)


def precisions(device: torch.device) -> list[str]:
    """The precisions the torch runtime offers on `device` (fp16 and tf32 on a GPU only)."""
    return [p for p in PRECISIONS if device.type == "cuda" or p not in ("fp16", "tf32")]


def lower_precisions(device: torch.device) -> list[str]:
    """Those of `precisions` other than fp32."""
    return [p for p in precisions(device) if p != "fp32"]


def assert_graphs_match_eager(captured: torch.Tensor, eager: torch.Tensor, device: torch.device) -> None:
    assert captured.shape == eager.shape and captured.dtype == eager.dtype
    assert (captured - eager).abs().max().item() <= GRAPHS_VS_EAGER[device.type]


def test_device_names_are_checked():
    assert resolve_device("cpu") == torch.device("cpu") and device_label(torch.device("cpu")) == "cpu"
    for name, message in (("gpu", "unknown device"), ("cuda:x", "unknown device"), ("", "unknown device"),
                          (0, "device must be text")):
        with pytest.raises(UserError, match=message):
            resolve_device(name)


def test_auto_chooses_the_first_gpu_else_the_cpu():
    assert resolve_device("auto") == torch.device("cuda:0" if CUDA else "cpu")


@without_cuda
def test_cuda_is_refused_without_a_gpu():
    for name in ("cuda", "cuda:0", "cuda:1"):
        with pytest.raises(UserError, match="no usable CUDA GPU"):
            resolve_device(name)


@with_cuda
def test_cuda_names_resolve_to_a_present_gpu():
    count = torch.cuda.device_count()
    assert resolve_device("cuda") == resolve_device("cuda:0") == torch.device("cuda:0")
    assert resolve_device("cuda", local_rank=count - 1) == torch.device(f"cuda:{count - 1}")
    with pytest.raises(UserError, match=rf"there are only {count} CUDA GPU"):
        resolve_device(f"cuda:{count}")
    assert device_label(torch.device("cuda:0")) == f"cuda:0 ({torch.cuda.get_device_name(0)})"


def test_the_precisions_a_device_offers(device):
    for precision in PRECISIONS:
        if precision in precisions(device):
            check_precision(precision, device)
            assert EngineSetting(runtime="torch", precision=precision, device=str(device)).resolved_device() == device
        else:
            with pytest.raises(UserError, match=f"{precision} needs a CUDA GPU"):
                EngineSetting(runtime="torch", precision=precision, device=str(device)).resolved_device()
    with pytest.raises(UserError, match="unknown precision"):
        check_precision("fp8", device)


def test_precision_and_runtime_device_pairs():
    with pytest.raises(UserError, match="fp16 needs a CUDA GPU"):
        check_precision("fp16", torch.device("cpu"))
    onnx = EngineSetting(runtime="onnx", precision="int8", device="auto")
    assert onnx.resolved_device() == torch.device("cpu")  # ONNX Runtime is the CPU build
    # asked for CUDA: absent here, or ONNX Runtime cannot use it
    with pytest.raises(UserError, match="runtime onnx runs on the CPU only" if CUDA else "no usable CUDA GPU"):
        EngineSetting(runtime="onnx", precision="fp32", device="cuda").resolved_device()
    with pytest.raises(UserError, match="unknown device"):
        EngineSetting(runtime="onnx", precision="fp32", device="tpu").resolved_device()


@pytest.mark.parametrize("height, width, size", [(480, 640, 224), (48, 64, 112), (224, 224, 224), (1, 1, 14)])
def test_on_device_preprocessing_agrees_with_cv2_within_one_intensity(device, height, width, size):
    rng = np.random.default_rng(height)
    frames = [rng.integers(0, 256, (height, width, 3), np.uint8) for _ in VIEW_NAMES]
    frames[1][:] = 255  # saturated
    frames[2][:] = 0  # black
    on_cpu = model_input(frames, size)
    prepared = model_input_on_device(frames, size, device)
    assert prepared.device == device
    on_device = prepared.cpu().numpy()
    assert on_device.shape == on_cpu.shape == (3, 3, size, size) and on_device.dtype == np.float32
    intensity = np.abs(on_device - on_cpu) * IMAGENET_STD.numpy()[None] * 255
    assert intensity.max() <= INTENSITY
    # flat frames, and frames already at the size, come out at the same intensities (1e-5: a GPU may divide by
    # 255 as a product with its reciprocal, a few ulps off; a level is 0.017)
    np.testing.assert_allclose(on_device[1:], on_cpu[1:], rtol=0, atol=1e-5)
    if (height, width) == (size, size):
        np.testing.assert_allclose(on_device, on_cpu, rtol=0, atol=1e-5)


def test_captured_calls_give_the_eager_outputs(device):
    weight = torch.randn(8, 4, device=device)

    def fn(x: torch.Tensor) -> torch.Tensor:
        return torch.tanh(x @ weight.T)

    calls = CapturedCalls(fn, torch.no_grad)
    assert calls.mode == "not run yet"
    for rows in (3, 5, 3):
        x = torch.randn(rows, 4, device=device)
        assert_graphs_match_eager(calls(x), fn(x), device)
    assert len(calls.calls) == 2 and calls.mode == CAPTURED[device.type]
    off = CapturedCalls(fn, torch.no_grad, capture=False)
    x = torch.randn(3, 4, device=device)
    assert_graphs_match_eager(off(x), fn(x), device)  # eager on static buffers: the same kernels
    assert off.mode == CAPTURE_OFF[device.type]
    single = CapturedCall(lambda x: x * 2, [torch.zeros(2, device=device)], torch.no_grad)
    assert single.mode == ("CUDA graph" if device.type == "cuda" else CAPTURED["cpu"])
    first = single(torch.ones(2, device=device))
    single(torch.full((2,), 5.0, device=device))
    assert torch.equal(first, torch.full((2,), 2.0, device=device))  # outputs are not overwritten by the next call


def test_beyond_the_graph_limit_calls_run_eagerly(device, monkeypatch):
    monkeypatch.setattr(captured_call, "MAX_GRAPHS", 2)
    calls = CapturedCalls(lambda x: x + 1, torch.no_grad)
    for rows in (1, 2, 3, 4):
        assert torch.equal(calls(torch.zeros(rows, device=device)), torch.ones(rows, device=device))
    assert len(calls.calls) == 2 and calls.eager_beyond_limit == 2 and calls.mode == CAPTURED[device.type]


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
def test_the_captured_halves_make_no_tensor_from_host_data(device, name):
    """Through CapturedCalls, as the runtime calls them: on a GPU every call must be captured (a host copy fails
    the capture and the calls fall back to eager); on the CPU the host-data record finds the same faults."""
    torch.manual_seed(0)
    model = load_model(bundled_models()[name.split()[1]]) if name.startswith("bundled") else TouchAnything(preset(name))
    encoder, head = model_halves(model.eval().to(device))
    size, (tokens, width) = model.config.image_size, model.frame_token_shape
    images, view_ids = torch.rand(3, 3, size, size, device=device), torch.arange(3, device=device)
    head_inputs = (torch.rand(8, tokens, width, device=device), torch.rand(2, 42, 3, device=device),
                   torch.arange(42, device=device), torch.arange(2, device=device) * 7)
    encode, predict = CapturedCalls(encoder, torch.no_grad), CapturedCalls(head, torch.no_grad)
    with HostData() as host:
        encoded, maps = encode(images, view_ids), predict(*head_inputs)
    assert encoded.shape == (tokens, width) and maps.shape[:2] == (2, 2)
    assert host.seen == [], host.seen
    assert encode.mode == predict.mode == CAPTURED[device.type]


def clip(count: int = 20) -> list[Snapshot]:
    rng = np.random.default_rng(3)
    joints = rng.uniform(-3, 3, (42, 3)).astype(np.float32)
    joints[:, 2] += 50
    return [Snapshot(i, i * 33_333, {v: rng.integers(0, 256, (48, 64, 3), np.uint8) for v in VIEW_NAMES}, joints,
                     np.ones(2, bool)) for i in range(count)]


def pressures(engine: StreamingEngine) -> np.ndarray:
    return np.array([p.pressure for s in clip() for p in engine.step(s)])


def test_the_engine_reports_its_device_and_capture_and_the_other_preprocessing_stays_close(device):
    torch.manual_seed(0)
    model = TouchAnything(preset("nano")).eval()
    engine = StreamingEngine(model, EngineSetting(device=str(device)))
    runtime = engine.runtime
    assert isinstance(runtime, TorchRuntime) and runtime.device == device
    assert runtime.capture == {"cpu": CAPTURED["cpu"], "cuda": "CUDA graphs (captured at the first call)"}[device.type]
    outputs = pressures(engine)
    assert runtime.capture == CAPTURED[device.type]
    # the other device's preprocessing on the same frames (the CPU's runtime prepares with cv2, a GPU's on the
    # GPU): within the measured bound of the predictions
    other = model_input if device.type == "cuda" else (lambda frames, size: model_input_on_device(frames, size, device))
    runtime.prepare = other
    engine.reset()
    assert np.nanmax(np.abs(outputs - pressures(engine))) < 0.02


def test_every_precision_of_the_device_stays_close_to_fp32(device):
    """bf16 (and on a GPU fp16 and tf32) through autocast, captured on a GPU like fp32, results float32."""
    torch.manual_seed(0)
    model = TouchAnything(preset("nano")).eval()
    reference = pressures(StreamingEngine(model, EngineSetting(device=str(device))))
    for precision in lower_precisions(device):
        engine = StreamingEngine(model, EngineSetting(device=str(device), precision=precision))
        low = pressures(engine)
        assert low.dtype == np.float32 and np.array_equal(np.isnan(low), np.isnan(reference)), precision
        assert np.nanmax(np.abs(low - reference)) < LOW_PRECISION_MAX[device.type][precision], precision
        assert engine.runtime.capture == CAPTURED[device.type], precision


@pytest.mark.parametrize("argv, message", [
    pytest.param(["replay", "EPISODE", "--headless", "--device", "cuda"], "no usable CUDA GPU", marks=without_cuda),
    pytest.param(["demo", "--headless", "--device", "cuda:0"], "no usable CUDA GPU", marks=without_cuda),
    pytest.param(["demo", "--headless", "--device", "cuda:99"], "there are only", marks=with_cuda),
    (["replay", "EPISODE", "--headless", "--precision", "fp16", "--device", "cpu"], "fp16 needs a CUDA GPU"),
    pytest.param(["replay", "EPISODE", "--headless", "--runtime", "onnx", "--device", "cuda"], "no usable CUDA GPU",
                 marks=without_cuda),
    pytest.param(["replay", "EPISODE", "--headless", "--runtime", "onnx", "--device", "cuda"],
                 "runtime onnx runs on the CPU only", marks=with_cuda),
    pytest.param(["eval", "--checkpoint", "CKPT", "--data", "DATA", "--device", "cuda"], "no usable CUDA GPU",
                 marks=without_cuda),
    (["eval", "--checkpoint", "CKPT", "--data", "DATA", "--precision", "fp16", "--device", "cpu"], "fp16 needs a CUDA GPU"),
])
def test_every_command_names_a_device_it_cannot_use_in_one_line(argv, message, episode_dir, sim_hdf5_root,
                                                                tiny_checkpoint, capsys):
    scene = Path(__file__).resolve().parents[2] / "scenes" / "sim.toml"
    values = {"EPISODE": str(episode_dir), "SCENE": str(scene), "CKPT": str(tiny_checkpoint), "DATA": str(sim_hdf5_root)}
    assert main([values.get(a, a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


@without_cuda
def test_live_keeps_the_rig_running_and_says_why_the_device_cannot_predict(capsys):
    scene = Path(__file__).resolve().parents[2] / "scenes" / "sim.toml"
    assert main(["live", "--scene", str(scene), "--headless", "--seconds", "1", "--device", "cuda"]) == 0
    captured = capsys.readouterr()
    assert "no prediction: device 'cuda' asked for, but this machine has no usable CUDA GPU" in captured.out
    assert captured.err == "" and "model     no model" in captured.out


def scene_on(tmp_path: Path, device: str) -> Path:
    """scenes/sim.toml with its model on `device`, written into `tmp_path`."""
    scene = (Path(__file__).resolve().parents[2] / "scenes" / "sim.toml").read_text().replace("../recordings", str(
        Path(__file__).resolve().parents[2] / "recordings"))
    path = tmp_path / f"{device.replace(':', '')}.toml"
    path.write_text(scene.replace('device = "auto"', f'device = "{device}"'))
    return path


def test_a_scene_names_the_device_of_its_model(tmp_path):
    assert read_scene(scene_on(tmp_path, "cpu")).model.setting.device == "cpu"
    assert read_scene(scene_on(tmp_path, "cuda:0")).model.setting.device == "cuda:0"


@without_cuda
def test_a_scene_whose_gpu_is_absent_runs_the_rig_without_a_model(tmp_path, capsys):
    assert main(["live", "--scene", str(scene_on(tmp_path, "cuda:0")), "--headless", "--seconds", "0.5"]) == 0
    assert "no prediction: device 'cuda:0' asked for" in capsys.readouterr().out


@with_cuda
def test_live_predicts_on_the_gpu_its_scene_names(tmp_path, capsys):
    assert main(["live", "--scene", str(scene_on(tmp_path, "cuda:0")), "--headless", "--seconds", "3"]) == 0
    out = capsys.readouterr().out
    assert "no prediction: device" not in out
    model = next(line for line in out.splitlines() if line.startswith("model     "))
    assert model.endswith(", CUDA graphs"), model  # every call of the engine captured
    assert int(out.split("summary   ")[1].split()[2]) > 0  # "N snapshots, M predictions, ..."


def test_the_exactness_benchmark_measures_the_bundled_nano(device):
    """benchmarks/gpu_exactness.py (whose GPU figures docs/engine.md reports) on the device: the streamed newest
    frame equals the batch forward, graphs equal eager, the lower precisions stay close and on a GPU keep every
    contact lamp (fp16 and tf32 on a GPU only), and the device's preprocessing is within one level of cv2's."""
    bench = runpy.run_path(str(Path(__file__).resolve().parents[2] / "benchmarks" / "gpu_exactness.py"))
    clip = bench["first_latency_clip"]([bench["episode_paths"](SAMPLE_DIR)[0]], BENCH_FRAMES[device.type])
    row = bench["measure"](load_model(bundled_models()["nano"]).to(device), clip, device)
    assert row["capture"] == CAPTURED[device.type]
    assert row["fp32 vs batch"] < TOLERANCE and row["eager vs graphs"] <= GRAPHS_VS_EAGER[device.type]
    assert {key for key in row if key.endswith(" vs fp32")} == {f"{p} vs fp32" for p in lower_precisions(device)}
    for precision in lower_precisions(device):
        low = row[f"{precision} vs fp32"]
        assert 0.0 <= low["max"] < LOW_PRECISION_MAX[device.type][precision], (precision, low)
        lamps = {"cpu": (0.0, 1.0), "cuda": (1.0, 1.0)}[device.type]  # a GPU's agreed on every hand-frame
        assert lamps[0] <= low["contact agreement"] <= lamps[1], (precision, low)
    assert row["preprocessing levels"] <= INTENSITY
    table = bench["markdown"]({"machine": "m", "device": str(device), "episode": "e", "frames": len(clip),
                               "models": {"nano": row}})
    assert f"| nano | {CAPTURED[device.type]} |" in table and ("| n/a |" in table) == (device.type == "cpu")


def test_tf32_is_a_gpu_precision_set_only_inside_its_context():
    """tf32 (fp32 weights, TensorFloat-32 matrix products on a GPU): refused on the CPU; its context sets CUDA's
    matmul and convolution mode and restores it after, also after an error; on the CPU it computes fp32 exactly;
    the GPU bench measures it beside fp32."""
    from touchanything.inference.evaluation.bench_gpu import gpu_settings
    from touchanything.inference.model.torch_device import autocast

    with pytest.raises(UserError, match="tf32 needs a CUDA GPU"):
        check_precision("tf32", torch.device("cpu"))
    with pytest.raises(UserError, match="tf32 needs a CUDA GPU"):
        EngineSetting(runtime="torch", precision="tf32", device="cpu").resolved_device()
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
