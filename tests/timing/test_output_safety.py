"""No command destroys what it reads (docs/data_safety.md): the output rule of `core.output_safety`, single
commands whose output is an input, lies in it or cannot be written (a full disk), and a property test running
every writing command with its output pointed at each of its inputs."""
from __future__ import annotations

import hashlib
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from touchanything.app.cli import main
from touchanything.core.errors import UserError
from touchanything.core.output_safety import check_output, replacing, replacing_folder, write_text
from touchanything.core.temporary_files import PARTIAL
from touchanything.inference.training.frame_cache import CACHE_DIR
from touchanything.viz.comparison_video import is_comparison_video, write_comparison_video

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "scenes" / "sim.toml"
NANO = REPO / "models" / "nano"


def checksums(*paths: Path) -> dict[Path, str]:
    """sha256 of every file under each path (a file: itself)."""
    files = [f for p in paths for f in ([p] if p.is_file() else sorted(p.rglob("*"))) if f.is_file()]
    return {f: hashlib.sha256(f.read_bytes()).hexdigest() for f in files}


def leftovers(*folders: Path) -> list[Path]:
    """Temporary outputs left anywhere under the folders."""
    return [p for folder in folders for p in folder.rglob(f"*{PARTIAL}*")]


def one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


# --- the rule itself --------------------------------------------------------------------------------


def test_replacing_renames_only_when_complete_and_leaves_nothing_on_error(tmp_path):
    out = tmp_path / "report.md"
    out.write_text("old")
    with pytest.raises(RuntimeError), replacing(out) as temporary:
        temporary.write_text("half")
        raise RuntimeError("interrupted")
    assert out.read_text() == "old" and leftovers(tmp_path) == []
    with replacing(out) as temporary:
        temporary.write_text("new")
        assert out.read_text() == "old" and temporary.parent == tmp_path and temporary.name.startswith(".report.md")
    assert out.read_text() == "new" and leftovers(tmp_path) == []
    with pytest.raises(UserError, match=r"report.md: not written \(Is a directory\)"), replacing(out) as temporary:
        temporary.mkdir()
        temporary.joinpath("x").write_text("")
        temporary.write_text("into a folder")
    assert out.read_text() == "new" and leftovers(tmp_path) == []


def test_replacing_folder_takes_the_place_only_when_complete(tmp_path):
    out = tmp_path / "dataset"
    out.mkdir()
    (out / "mine").write_text("keep")
    with pytest.raises(KeyboardInterrupt), replacing_folder(out, overwrite=True) as folder:
        (folder / "a").write_text("half")
        raise KeyboardInterrupt
    assert (out / "mine").read_text() == "keep" and sorted(tmp_path.iterdir()) == [out]
    with pytest.raises(UserError, match="not empty; pass --overwrite"), replacing_folder(out) as folder:
        (folder / "a").write_text("new")
    assert (out / "mine").read_text() == "keep" and sorted(tmp_path.iterdir()) == [out]
    with replacing_folder(out, overwrite=True) as folder:
        (folder / "a").write_text("new")
    assert [p.name for p in out.iterdir()] == ["a"] and sorted(tmp_path.iterdir()) == [out]


def test_check_output_cases(tmp_path):
    episode = tmp_path / "ep"
    episode.mkdir()
    (episode / "chest.mp4").write_bytes(b"video")
    (episode / "split.json").write_text("{}")
    (tmp_path / "link.mp4").symlink_to(episode / "chest.mp4")
    (tmp_path / "other.txt").write_text("someone's")
    (tmp_path / "file").write_text("")
    refused = {episode: "is an input", tmp_path / "link.mp4": "did not write",
               episode / "chest.mp4": "did not write", episode / ".." / "ep" / "chest.mp4": "did not write",
               tmp_path / "other.txt": "exists; pass --overwrite", tmp_path: "is a folder",
               tmp_path / "file" / "out.txt": "cannot be created"}
    for out, message in refused.items():
        with pytest.raises(UserError, match=message):
            check_output(out, [episode])
    for out in (episode / "chest.mp4", tmp_path / "link.mp4"):  # --overwrite never reaches an input
        with pytest.raises(UserError):
            check_output(out, [episode], overwrite=True)
    check_output(tmp_path / "other.txt", [episode], overwrite=True)
    check_output(episode / "split.json", [episode], own=lambda p: p.name == "split.json")
    check_output(episode / "new.mp4", [episode])  # a new file beside the data loses nothing
    check_output(tmp_path / "new" / "deeper" / "x.json", [episode])
    assert not (tmp_path / "new").exists() and leftovers(tmp_path) == []  # a check creates nothing
    with pytest.raises(UserError, match="holds the input"):
        check_output(tmp_path, [episode], overwrite=True, whole=True)
    with pytest.raises(UserError, match="exists and is not a folder"):
        check_output(tmp_path / "other.txt", [], folder=True)
    write_text(tmp_path / "made" / "r.md", "x")
    assert (tmp_path / "made" / "r.md").read_text() == "x"


# --- single commands: an output that is an input, lies in one or cannot be written -----------------------


def test_replay_refuses_the_episodes_own_video(episode_dir, capsys):
    before = checksums(episode_dir)
    for extra in ([], ["--overwrite"]):
        assert main(["replay", str(episode_dir), "--headless", "--out", str(episode_dir / "chest.mp4"), *extra]) == 2
        assert "did not write" in one_line(capsys)
    assert checksums(episode_dir) == before and leftovers(episode_dir) == []


def test_split_refuses_a_trajectory_as_its_output(sim_hdf5_root, tmp_path, capsys):
    root = shutil.copytree(sim_hdf5_root, tmp_path / "h5")
    before = checksums(root)
    trajectory = sorted(root.rglob("*.hdf5"))[0]
    for extra in ([], ["--overwrite"]):
        assert main(["split", str(root), "--out", str(trajectory), *extra]) == 2
        assert f"{trajectory}: would replace a file of the input" in one_line(capsys)
    assert checksums(root) == before
    assert main(["split", str(root)]) == 0  # an existing split.json (say the simulator's) is kept and named
    assert "split.json: a split is already there (" in capsys.readouterr().out and checksums(root) == before
    (root / "split.json").write_text("{not json")
    assert main(["split", str(root)]) == 2 and "it is kept: --overwrite replaces it" in one_line(capsys)
    assert main(["split", str(root), "--overwrite"]) == 0
    capsys.readouterr()


def test_bench_finds_an_unwritable_out_before_any_work(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    started = time.monotonic()
    assert main(["bench", "--quick", "--device", "cpu", "--out", str(tmp_path / "notes.txt" / "bench")]) == 2
    assert time.monotonic() - started < 20  # a quick bench takes minutes; the check, no model loaded, none
    assert "cannot be created (" in one_line(capsys) and (tmp_path / "notes.txt").read_text() == "mine"


def limited_run(args: list[str], max_bytes: int) -> subprocess.CompletedProcess:
    """`touchanything ARGS` in a process whose files may not grow past `max_bytes` (RLIMIT_FSIZE): a write
    past it fails as on a full disk (EFBIG instead of ENOSPC; SIGXFSZ ignored so the write returns)."""
    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, resource.RLIM_INFINITY))

    return subprocess.run([sys.executable, "-m", "touchanything.app.cli", *args], capture_output=True, text=True,
                          preexec_fn=limit, timeout=300, cwd=Path(__file__).parent)


@pytest.mark.parametrize("command", ["grids", "split"])
def test_a_full_disk_while_writing_grids_or_a_report_is_one_line_and_no_half_file(command, episode_dir,
                                                                                   sim_hdf5_root, tmp_path):
    if command == "grids":
        folder, args, output = episode_dir, ["grids", str(episode_dir)], episode_dir / "pressure_grids.npz"
    else:
        folder = shutil.copytree(sim_hdf5_root, tmp_path / "h5")
        args, output = ["split", str(folder), "--overwrite"], folder / "split.json"
    before = checksums(folder)
    result = limited_run(args, max_bytes=64)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip() == f"touchanything {command}: error: {output}: not written (File too large)"
    assert checksums(folder) == before and leftovers(folder) == []


# --- every writing command, its output pointed at each of its inputs ---------------------------------


@pytest.fixture
def inputs(tmp_path, episode_dir, sim_hdf5_root) -> dict[str, Path]:
    """Copies of every kind of input a writing command reads."""
    model = shutil.copytree(NANO, tmp_path / "model")
    scene = shutil.copy(SCENE, tmp_path / "sim.toml")
    return {"episode": episode_dir, "h5": shutil.copytree(sim_hdf5_root, tmp_path / "h5"),
            "checkpoint": model / "best_model.pth", "config": REPO / "configs" / "nano.yaml", "scene": Path(scene),
            "video": episode_dir / "chest.mp4"}


def writing_commands(i: dict[str, Path]) -> list[tuple[list[str], list[Path], list[str]]]:
    """(arguments with {} for the output, the inputs, the output options) of every command that writes."""
    ep, h5, ckpt = str(i["episode"]), str(i["h5"]), str(i["checkpoint"])
    return [
        (["replay", ep, "--checkpoint", ckpt, "--out", "{}"], [i["episode"], i["checkpoint"]], ["--overwrite"]),
        (["replay", ep, "--checkpoint", ckpt, "--headless", "--rerun", "{}"], [i["episode"], i["checkpoint"]], ["--overwrite"]),
        (["demo", ep, "--headless", "--out", "{}"], [i["episode"]], ["--overwrite"]),
        (["live", "--scene", str(i["scene"]), "--headless", "--rerun", "{}"], [i["scene"]], ["--overwrite"]),
        (["pose", str(i["video"]), "--out", "{}"], [i["video"]], ["--overwrite"]),
        (["split", h5, "--out", "{}"], [i["h5"]], ["--overwrite"]),
        (["eval", "--checkpoint", ckpt, "--data", h5, "--out", "{}"], [i["checkpoint"], i["h5"]], []),
        (["eval", "--checkpoint", ckpt, "--data", h5, "--rerun", "{}"], [i["checkpoint"], i["h5"]], ["--overwrite"]),
        (["bench", "--quick", "--device", "cpu", "--data", ep, "--models", str(i["checkpoint"].parent), "--out", "{}"],
         [i["episode"], i["checkpoint"].parent], []),
        (["convert", ep, "{}"], [i["episode"]], []),
        (["train", "--config", str(i["config"]), "--data", h5, "--out", "{}"], [i["config"], i["h5"]], []),
        (["export-onnx", "--checkpoint", ckpt, "--out", "{}"], [i["checkpoint"]], ["--overwrite"]),
        (["export-lerobot", ep, "{}"], [i["episode"]], ["--overwrite"]),
        (["record", "--scene", str(i["scene"]), "--seconds", "1", "--out", "{}"], [i["scene"]], []),
    ]


def targets(paths: list[Path]) -> list[Path]:
    """Each input, and each file inside an input folder that is the user's (not the training frame cache the
    project writes beside a dataset, which earlier tests may have left in a shared fixture)."""
    def users(f: Path) -> bool:
        return f.is_file() and CACHE_DIR not in f.parts
    return [t for p in paths for t in ([p] if p.is_file() else [p, *sorted(f for f in p.rglob("*") if users(f))])]


def test_no_command_changes_an_input_when_its_output_points_at_it(inputs, capsys):
    before = checksums(*inputs.values())
    for args, read, options in writing_commands(inputs):
        for target in targets(read):
            if args[0] == "split" and target.name == "split.json":
                continue  # split's own output: replaced (test_split_refuses_a_trajectory_as_its_output)
            for extra in ([], options):
                command = [str(target) if a == "{}" else a for a in args] + extra
                assert main(command) == 2, command
                one_line(capsys)
    assert checksums(*inputs.values()) == before
    assert leftovers(*(p for p in inputs.values() if p.is_dir())) == []


def test_grids_refuses_a_grids_file_that_links_to_its_input(episode_dir, capsys):
    grids = episode_dir / "pressure_grids.npz"
    grids.unlink()
    grids.symlink_to(episode_dir / "jq_pressure.json")
    before = checksums(episode_dir)
    assert main(["grids", str(episode_dir)]) == 2
    assert "is an input" in one_line(capsys) and checksums(episode_dir) == before


def test_an_earlier_comparison_video_is_replaced_another_is_not(episode_dir, tmp_path, capsys):
    video = tmp_path / "out.mp4"
    write_comparison_video(video, (np.zeros((16, 16, 3), np.uint8) for _ in range(3)))
    assert is_comparison_video(video) and not is_comparison_video(episode_dir / "chest.mp4")
    other = shutil.copy(episode_dir / "chest.mp4", tmp_path / "theirs.mp4")
    assert main(["replay", str(episode_dir), "--out", str(other)]) == 2
    assert "exists; pass --overwrite" in one_line(capsys)
    check_output(video, [episode_dir], own=is_comparison_video)  # passes: replaced without --overwrite
