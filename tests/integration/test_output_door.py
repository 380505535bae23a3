"""Every writing command × every fault at each output it makes (docs/data_safety.md): a symbolic link
or a hard link to a file outside (the user's), a foreign file of the user's at the output's name, and a full disk
(a real tmpfs, as root). Each run ends with every file the project did not write byte-identical, one line, and
the documented exit status; with `--overwrite` a link itself is replaced, never what it reaches. A command the
CLI gains must be listed here (writing, with its outputs) or among the read-only ones."""
from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.conftest import write_episode
from tests.integration.test_input_links import digest
from touchanything.app.cli import COMMANDS, build_parser, main
from touchanything.core.temporary_files import OWNER, PARTIAL
from touchanything.inference.evaluation.bench_report import OUTPUT_FILES as BENCH_FILES

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "scenes" / "sim.toml"
NANO = REPO / "models" / "nano"
READ_ONLY = {"info", "devices"}
FAULTS = ("symlink", "hardlink", "foreign")
EPISODE_FILES = ("chest.mp4", "left.mp4", "right.mp4", "wilor_hands.json", "rokoko_hands.json", "vive_poses.json",
                 "jq_pressure.json", "pressure_grids.npz")


@dataclass(frozen=True)
class Case:
    """A writing command: `argv` with {out} for its output, {ep}/{root}/{h5}/{ckpt}/{video} for its inputs; `outputs`:
    the files it makes, relative to the folder {out} lies in; `overwrite`: its option to replace, or None; `cheap`:
    a full run is quick enough to repeat for every fault."""

    name: str
    argv: tuple[str, ...]
    out: str
    outputs: tuple[str, ...]
    overwrite: str | None = "--overwrite"
    cheap: bool = False


CASES = (
    Case("replay", ("replay", "{ep}", "--checkpoint", "{ckpt}", "--headless", "--out", "{out}"), "out.mp4", ("out.mp4",),
         cheap=True),
    Case("replay --rerun", ("replay", "{ep}", "--checkpoint", "{ckpt}", "--headless", "--rerun", "{out}"), "out.rrd",
         ("out.rrd",), cheap=True),
    Case("demo", ("demo", "{ep}", "--headless", "--out", "{out}"), "demo.mp4", ("demo.mp4",)),
    Case("live", ("live", "--scene", str(SCENE), "--headless", "--seconds", "1", "--rerun", "{out}"), "live.rrd",
         ("live.rrd",)),
    Case("pose", ("pose", "{video}", "--out", "{out}"), "hands.json", ("hands.json",)),
    Case("split", ("split", "{h5}", "--out", "{out}"), "split.json", ("split.json",), cheap=True),
    Case("eval", ("eval", "--checkpoint", "{ckpt}", "--data", "{h5}", "--out", "{out}"), "results",
         ("results/results.json", "results/results.md"), cheap=True),
    Case("eval --rerun", ("eval", "--checkpoint", "{ckpt}", "--data", "{h5}", "--rerun", "{out}"), "eval.rrd",
         ("eval.rrd",)),
    Case("bench", ("bench", "--quick", "--device", "cpu", "--data", "{ep}", "--models", "{models}", "--out", "{out}"),
         "bench", tuple(f"bench/{name}" for name in BENCH_FILES)),
    Case("convert", ("convert", "{root}", "{out}"), "h5",
         ("h5/Home/pick_up_bottle/20260319_211038_740.hdf5", "h5/conversion_report.txt"), cheap=True),
    Case("train", ("train", "--config", str(REPO / "configs" / "nano.yaml"), "--data", "{h5}", "--out", "{out}"), "run",
         ("run/best_model.pth", "run/last.pth", "run/config.yaml")),
    Case("export-onnx", ("export-onnx", "--checkpoint", "{ckpt}", "--out", "{out}"), "onnx",
         ("onnx/engine.json", "onnx/encoder.onnx", "onnx/head.onnx")),
    Case("export-lerobot", ("export-lerobot", "{root}", "{out}"), "lerobot", ("lerobot/meta/info.json",), cheap=True),
    Case("simulate", ("simulate", "{out}", "--episodes", "1", "--seconds", "1"), "sim", ("sim/split.json",),
         cheap=True),
    Case("record", ("record", "--scene", str(SCENE), "--seconds", "1", "--out", "{out}"), "rec",
         tuple(f"rec/{name}" for name in EPISODE_FILES), overwrite=None),
    Case("grids", ("grids", "{out}"), "episode", ("episode/pressure_grids.npz",), cheap=True),
)


def test_every_command_is_listed_as_writing_or_read_only():
    commands = set(build_parser()._subparsers._group_actions[0].choices)
    assert len(commands) == len(COMMANDS)
    assert commands == {case.argv[0] for case in CASES} | READ_ONLY


@pytest.fixture(scope="module")
def sources(tmp_path_factory, sim_hdf5_root) -> dict[str, Path]:
    """The inputs the commands read (never written: checked by digest)."""
    base = tmp_path_factory.mktemp("door")
    root = base / "raw"
    episode = write_episode(root / "Home" / "pick_up_bottle" / "20260319_211038_740", frames=12)
    return {"root": root, "ep": episode, "h5": sim_hdf5_root, "ckpt": NANO / "best_model.pth", "models": NANO,
            "video": episode / "chest.mp4"}


def arguments(case: Case, sources: dict[str, Path], base: Path) -> list[str]:
    """The case's command line with its output in `base` (grids: a copy of the episode there, its output inside)."""
    if case.name == "grids" and not (base / case.out).exists():
        shutil.copytree(sources["ep"], base / case.out, symlinks=True)
        (base / case.out / "pressure_grids.npz").unlink()
    values = {key: str(path) for key, path in sources.items()} | {"out": str(base / case.out)}
    return [part.format(**values) for part in case.argv]


def plant(fault: str, path: Path, sentinel: Path) -> None:
    """The fault at `path`: a link to the user's `sentinel`, or a foreign file of the user's."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if fault == "symlink":
        path.symlink_to(sentinel)
    elif fault == "hardlink":
        os.link(sentinel, path)
    else:
        path.write_text("my own notes, not touchanything's\n")


def temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if PARTIAL in p.name or p.name.endswith(OWNER)]


def planted_run(case: Case, fault: str, sources: dict[str, Path], tmp_path: Path, capsys,
                extra: tuple[str, ...] = ()) -> tuple[int, str, dict[str, str], list[Path]]:
    """Run the case with `fault` at each of its outputs; (exit status, stderr, the user's files' digest before, the
    planted paths)."""
    base, users = tmp_path / "work", tmp_path / "users"
    base.mkdir()
    users.mkdir()
    argv = arguments(case, sources, base)
    planted = []
    for k, output in enumerate(case.outputs):
        sentinel = users / f"sentinel-{k}"
        sentinel.write_text(f"the user's file {k}\n")
        plant(fault, base / output, sentinel)
        planted.append(base / output)
    before = digest(users) | {str(p): digest(p)[str(p)] for p in planted if fault == "foreign"}
    inputs_before = {key: digest(path) for key, path in sources.items()}
    capsys.readouterr()
    code = main(argv + list(extra))
    err = capsys.readouterr().err
    assert {key: digest(path) for key, path in sources.items()} == inputs_before
    return code, err, before, planted


@pytest.mark.parametrize("fault", FAULTS)
@pytest.mark.parametrize("case", CASES, ids=lambda case: case.name)
def test_a_fault_at_an_output_is_refused_before_any_work(case, fault, sources, tmp_path, capsys):
    code, err, before, planted = planted_run(case, fault, sources, tmp_path, capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, (code, err)
    assert str(tmp_path / "work") in err, err  # the output refused is named
    assert digest(tmp_path / "users") | {str(p): digest(p)[str(p)] for p in planted if fault == "foreign"} == before
    assert all(p.is_symlink() for p in planted) if fault == "symlink" else all(p.is_file() for p in planted)
    assert temporaries(tmp_path) == []


CHEAP = [case for case in CASES if case.cheap and case.overwrite]


@pytest.mark.parametrize("fault", ("symlink", "hardlink"))
@pytest.mark.parametrize("case", CHEAP, ids=lambda case: case.name)
def test_with_overwrite_a_link_is_replaced_never_what_it_reaches(case, fault, sources, tmp_path, capsys):
    code, err, before, planted = planted_run(case, fault, sources, tmp_path, capsys, extra=(case.overwrite,))
    assert code == 0, err
    assert digest(tmp_path / "users") == before  # the files the links reached are the user's still
    if case.name not in ("export-lerobot", "simulate"):  # a folder built as a whole holds only what it writes
        assert all(p.is_file() and not p.is_symlink() and p.stat().st_nlink == 1 for p in planted)
    assert temporaries(tmp_path) == []


@pytest.fixture(scope="module")
def full_disk(tmp_path_factory) -> Path:
    """A real tmpfs with not one byte free."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    disk = tmp_path_factory.mktemp("full")
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", str(disk)], check=True)
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=True)


@pytest.mark.parametrize("case", CASES, ids=lambda case: case.name)
def test_a_full_disk_is_one_line_before_any_work(case, sources, full_disk, capsys):
    base = full_disk / case.name.replace(" ", "_")
    base.mkdir()
    argv = arguments(case, sources, base)
    filler = full_disk / f"filler-{case.name.replace(' ', '_')}"
    with open(filler, "wb", buffering=0) as handle:
        try:
            while True:
                handle.write(b"\0" * 4096)
        except OSError:
            pass
    try:
        before = digest(base)
        capsys.readouterr()
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1, (code, err)
        assert "No space left on device" in err and "Traceback" not in err, err
        assert digest(base) == before and temporaries(base) == []
    finally:
        filler.unlink()


def test_a_screenshot_takes_a_free_name_never_a_taken_one(tmp_path):
    from touchanything.viz.dashboard.dashboard import free_name

    shot = tmp_path / "dashboard_20261128_120000.png"
    assert free_name(shot) == shot
    shot.write_text("the user's")
    (tmp_path / "dashboard_20261128_120000_2.png").symlink_to(tmp_path / "nowhere")  # a dangling link is taken too
    assert free_name(shot) == tmp_path / "dashboard_20261128_120000_3.png"
