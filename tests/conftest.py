"""Shared fixtures: real episode folders written through the project's writer, and the official files."""
from __future__ import annotations

import os
from pathlib import Path

if "PYTEST_XDIST_WORKER_COUNT" in os.environ:
    # A worker of `pytest -n N` shares the cores with N - 1 others: torch's (OpenMP) threads default to every core, and
    # 2 workers × 2 spinning threads on 2 cores took 209 s where 1 thread each took 160 s (the heaviest modules). Set
    # before torch is first imported; the CLI processes that tests start inherit it. The serial run keeps every core.
    os.environ.setdefault("OMP_NUM_THREADS", str(max(1, (os.cpu_count() or 1) // int(os.environ["PYTEST_XDIST_WORKER_COUNT"]))))
# The user caches the suite fills (ONNX exports of the bundled models, simulated episodes) live beside the checkout's
# pytest cache, not in the user's home: a run never serves the user a test's file, nor a test the user's.
os.environ["XDG_CACHE_HOME"] = str(Path(__file__).resolve().parents[1] / ".pytest_cache" / "xdg")

import numpy as np
import pytest

from helpers.episode_files import write_quality
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.devices.episodes.episode_files import write_camera_matrices
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter

OFFICIAL_DIR = Path(__file__).resolve().parents[2] / "shared" / "reference" / "egotouch"


@pytest.fixture(scope="session")
def official_dir() -> Path:
    if not OFFICIAL_DIR.is_dir():
        pytest.skip("../shared/reference/egotouch is not beside the checkout")
    return OFFICIAL_DIR


def wilor_hands(frame: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Plausible WiLoR-range joints (x, y in [-5, 5], z around 50); the right hand vanishes every 7th frame."""
    joints = rng.uniform(-3, 3, size=(2, 21, 3)).astype(np.float32)
    joints[..., 2] = 50 + rng.uniform(-5, 5, size=(2, 21))
    return joints, np.array([True, frame % 7 != 3])


def glove_sample(frame: int, rng: np.random.Generator) -> np.ndarray:
    """(2, 256) uint8: small noise with a press ramping up in the middle of the episode."""
    raw = rng.integers(0, 6, size=(2, 256)).astype(np.int32)
    press = int(200 * max(0.0, np.sin(frame / 6.0)))
    raw[:, 0:60] += press
    return np.clip(raw, 0, 255).astype(np.uint8)


def frame_image(view: int, frame: int, size: tuple[int, int]) -> np.ndarray:
    """A smooth test picture that differs per view and frame (compresses well, decodes close)."""
    h, w = size
    y, x = np.mgrid[0:h, 0:w]
    image = np.empty((h, w, 3), np.uint8)
    image[..., 0] = (x * 255 // max(w - 1, 1) + 7 * frame) % 256
    image[..., 1] = (y * 255 // max(h - 1, 1) + 40 * view) % 256
    image[..., 2] = (60 * view + 5 * frame) % 256
    return image


def write_episode(folder: Path, frames: int = 40, size: tuple[int, int] = (48, 64), seed: int = 0,
                  views: tuple[str, ...] = VIEW_NAMES) -> Path:
    """A complete raw episode folder written by RawEpisodeWriter."""
    rng = np.random.default_rng(seed)
    with RawEpisodeWriter(folder, crf=10) as writer:
        for i in range(frames):
            quat = np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (2, 1))
            writer.write(EpisodeFrame(
                images={v: frame_image(k, i, size) for k, v in enumerate(views)},
                wilor=wilor_hands(i, rng),
                rokoko=(rng.normal(0, 0.1, size=(2, 21, 3)).astype(np.float32), np.array([True, True])),
                glove=(glove_sample(i, rng), np.array([True, True]), quat),
                trackers=(rng.normal(0, 1, size=(3, 7)).astype(np.float32), np.array([True, True, i % 5 != 0])),
            ))
    write_quality(folder / "quality_issues.json", {"left": 0.01, "right": 0.3})
    write_camera_matrices(folder / "camera_matrix.txt", {"chest": np.array([[500, 0, 32], [0, 500, 24], [0, 0, 1.0]])})
    return folder


@pytest.fixture
def episode_dir(tmp_path: Path) -> Path:
    return write_episode(tmp_path / "raw" / "Home" / "pick_up_bottle" / "20260319_211038_740")


@pytest.fixture(scope="session")
def sim_raw_root(tmp_path_factory) -> Path:
    """Three short simulated raw episodes, with their split.json (seed 5). Read only."""
    from touchanything.devices.sim.dataset_generator import SimulationConfig, simulate_dataset

    raw = tmp_path_factory.mktemp("sim_raw")
    simulate_dataset(raw, SimulationConfig(episodes=3, seconds=2.0, seed=5, workers=1))
    return raw


@pytest.fixture(scope="session")
def sim_hdf5_root(sim_raw_root, tmp_path_factory) -> Path:
    """The three episodes of `sim_raw_root` converted to HDF5, with their split.json."""
    from touchanything.devices.episodes.dataset_conversion import convert_dataset

    out = tmp_path_factory.mktemp("sim_h5")
    convert_dataset(sim_raw_root, out, compression_level=1)
    return out


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory) -> Path:
    """A randomly initialised `tiny` model saved in the official checkpoint format."""
    import torch

    from touchanything.inference.model.checkpoint import build_model, save_checkpoint
    from touchanything.inference.model.model_config import PRESETS

    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("ckpt") / "best_model.pth"
    save_checkpoint(path, build_model(PRESETS["tiny"]))
    return path


@pytest.fixture(scope="session")
def perturbed_nano(tmp_path_factory) -> Path:
    """A copy of the bundled nano with one weight changed, saved as a project checkpoint (same architecture,
    other weights: its SHA-256 differs from nano's)."""
    import torch

    from touchanything.app.sessions.bundled import MODELS_DIR
    from touchanything.inference.model.checkpoint import load_model, save_checkpoint

    model = load_model(MODELS_DIR / "nano" / "best_model.pth")
    with torch.no_grad():
        next(p for p in model.parameters() if p.is_floating_point()).view(-1)[0] += 0.5
    path = tmp_path_factory.mktemp("perturbed") / "best_model.pth"
    save_checkpoint(path, model)
    return path


@pytest.fixture(scope="session")
def perturbed_nano_export(perturbed_nano, tmp_path_factory) -> Path:
    """`perturbed_nano` exported (fp32 + int8) by the command line, once per test process: an export takes
    8-18 s on 2 cores. Tests copy it where they change or replace a folder."""
    from touchanything.app.cli import main

    out = tmp_path_factory.mktemp("perturbed_export") / "graphs"
    assert main(["export-onnx", "--checkpoint", str(perturbed_nano), "--out", str(out), "--int8"]) == 0
    return out


@pytest.fixture(autouse=True)
def restore_torch_threads():
    """Streaming engines set torch's process-wide thread count; give every test the default back."""
    import torch

    threads = torch.get_num_threads()
    yield
    torch.set_num_threads(threads)


def _free_display_number() -> int:
    for number in range(90, 200):
        if not Path(f"/tmp/.X11-unix/X{number}").exists() and not Path(f"/tmp/.X{number}-lock").exists():
            return number
    raise RuntimeError("no free X display number")


@pytest.fixture(scope="session")
def x_display():
    """An X display for the dashboard: $DISPLAY when it is reachable, else an Xvfb started here (1920×1080)."""
    import shutil
    import subprocess
    import time

    from touchanything.viz.display import display_problem

    if os.environ.get("DISPLAY") and display_problem() is None:
        yield os.environ["DISPLAY"]
        return
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb xauth)")
    display = f":{_free_display_number()}"
    # -noreset: an X server resets when its last client leaves, and a client connecting during the reset
    # fails (GLFW then aborts the process); the tests open one dashboard after another.
    server = subprocess.Popen(["Xvfb", display, "-screen", "0", "1920x1080x24", "-nolisten", "tcp", "-noreset"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 15
        while display_problem(display) is not None:
            assert server.poll() is None and time.monotonic() < deadline, f"Xvfb {display} did not start"
            time.sleep(0.05)
        yield display
    finally:
        server.terminate()
        server.wait(5)


@pytest.fixture
def dashboard_display(x_display, monkeypatch):
    monkeypatch.setenv("DISPLAY", x_display)
    return x_display


TIMING_DIR = Path(__file__).resolve().parent / "timing"
"""The folder of the tests that measure time (rates, latencies, deadlines) or hold a machine resource one test at a
time (the simulated rig's UDP ports and ptys, an X server of their own), or export ONNX graphs in a low-priority child
process (a busy worker beside it starves it): `make test` runs them, and every test that uses the X display, one by
one after the others, which run in parallel worker processes (pytest-xdist), so that no other test's load can slow
them."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests that use the X display carry the `display` marker (deselect them with `-m 'not display'`); those and
    every test under tests/timing/ carry the `serial` marker. The folder decides, not a list of modules: a module
    that must run serially goes to tests/timing/."""
    for item in items:
        display = "x_display" in getattr(item, "fixturenames", ())
        if display:
            item.add_marker(pytest.mark.display)
        if display or item.path.resolve().is_relative_to(TIMING_DIR):
            item.add_marker(pytest.mark.serial)
