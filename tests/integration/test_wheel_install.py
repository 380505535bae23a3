"""Installed like any Python package: the wheel the project builds holds only the `touchanything` namespace and
the files it ships (models, their atlas, the sample), and installed — without network, into a scratch environment
that reuses the installed dependencies — its `demo --headless` and a `replay` of a bundled episode run from a folder
outside the checkout, finding those files through the installed package (`importlib.resources`)."""
from __future__ import annotations

import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


def source_copy(target: Path) -> Path:
    """The checkout's files as git sees them (tracked, and untracked ones not ignored), without build leftovers."""
    listed = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"], cwd=ROOT,
                            capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, listed):
        if (ROOT / name).is_file():
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, target / name)
    return target


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    source, out = tmp_path_factory.mktemp("source"), tmp_path_factory.mktemp("wheel")
    source_copy(source)
    build = "import sys; from setuptools import build_meta; print(build_meta.build_wheel(sys.argv[1]))"
    proc = subprocess.run([sys.executable, "-c", build, str(out)], cwd=source, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out / proc.stdout.split()[-1]


def test_the_wheel_holds_the_namespace_and_what_ships_with_it(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert {name.split("/")[0] for name in names} == {"touchanything", "touchanything-0.1.0.dist-info"}
    layout = {name.rpartition("/")[2] for name in names if name.startswith("touchanything/core/layouts/default/")}
    assert layout == {p.name for p in (ROOT / "core" / "layouts" / "default").glob("*.json")}
    assert "touchanything/app/cli.py" in names and "touchanything/inference/engine/streaming_engine.py" in names
    for model in (p.parent.name for p in (ROOT / "models").glob("*/best_model.pth")):
        assert {f"touchanything/models/{model}/{f}" for f in ("best_model.pth", "config.yaml", "model_card.json")} <= set(names)
    assert "touchanything/models/atlas/engine.json" in names
    sample = {n.removeprefix("touchanything/sample/") for n in names if n.startswith("touchanything/sample/")}
    assert sample == {p.relative_to(ROOT / "recordings" / "sample").as_posix()
                      for p in (ROOT / "recordings" / "sample").rglob("*") if p.is_file() and "__pycache__" not in p.parts}


def scratch_environment(wheel: Path, where: Path) -> Path:
    """A venv at `where` whose site-packages reach this one's dependencies (a .pth line) and hold the wheel,
    installed with no index; its `touchanything` command."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(where)], check=True)
    python = where / "bin" / "python"
    site = Path(subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    (site / "dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--quiet", "--no-deps", "--no-index",
                    str(wheel)], check=True, capture_output=True)
    return where / "bin" / "touchanything"


def test_the_installed_wheel_runs_the_demo_and_a_replay_outside_the_checkout(wheel, tmp_path):
    command = scratch_environment(wheel, tmp_path / "env")
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    where = subprocess.run([command.parent / "python", "-c", "import touchanything.app.sessions.bundled as b; "
                            "print(b.MODELS_DIR); print(b.SAMPLE_DIR)"], cwd=outside, capture_output=True, text=True,
                           check=True).stdout.split()
    installed = tmp_path / "env" / "lib"
    assert all(Path(p).is_relative_to(installed) for p in where), where  # the installed copies, not the checkout
    demo = subprocess.run([command, "demo", "--headless"], cwd=outside, capture_output=True, text=True, timeout=900)
    assert demo.returncode == 0, demo.stderr[-2000:]
    assert "setting   pico/torch-fp32/all" in demo.stdout and (outside / "recordings" / "demo.mp4").stat().st_size > 100_000
    episode = next(Path(where[1]).glob("Office/*/*"))
    replay = subprocess.run([command, "replay", str(episode), "--headless", "--out", "office.mp4"], cwd=outside,
                            capture_output=True, text=True, timeout=900)
    assert replay.returncode == 0, replay.stderr[-2000:]
    assert "frames    300 written, 300 with a prediction" in replay.stdout and (outside / "office.mp4").is_file()
