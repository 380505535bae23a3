"""An ONNX export carries the SHA-256 of the weights it was made from (in engine.json and in every
graph file), running it beside other weights is refused naming both, exporting again replaces only the
export's own files in its folder, the user cache is keyed and checked by the same digest, and
`replay`/`demo`/`live` run an export folder with `--onnx DIR`."""
from __future__ import annotations

import hashlib
import itertools
import json
import os
import shutil
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from tests.conftest import write_episode
from tests.timing.test_output_safety import limited_run
from touchanything.app.cli import main
from touchanything.app.commands.live_command import open_live_session
from touchanything.app.sessions.bundled import MODELS_DIR
from touchanything.app.sessions.scene import read_scene
from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.live_engine import LiveEngine
from touchanything.inference.engine.onnx_cache import onnx_cache_dir
from touchanything.inference.engine.onnx_export import weights_sha256
from touchanything.inference.engine.onnx_export_folder import earlier_files
from touchanything.inference.engine.onnx_runtime import OnnxRuntime
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.checkpoint import load_model, save_checkpoint

NANO = MODELS_DIR / "nano" / "best_model.pth"
SCENES = Path(__file__).resolve().parents[2] / "scenes"


def reference_sha256(model: torch.nn.Module) -> str:
    """The documented definition, written out here: every state-dict entry in name order as
    "name|dtype|shape|" followed by its raw bytes."""
    digest = hashlib.sha256()
    for name in sorted(model.state_dict()):
        tensor = model.state_dict()[name].detach().cpu().contiguous()
        digest.update(f"{name}|{tensor.dtype}|{tuple(tensor.shape)}|".encode())
        digest.update(bytes(tensor.numpy().data))
    return digest.hexdigest()


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def nano_export(tmp_path_factory) -> Path:
    """The bundled nano exported (fp32 only) by the command line."""
    out = tmp_path_factory.mktemp("export") / "nano"
    assert main(["export-onnx", "--checkpoint", str(NANO), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def perturbed(perturbed_nano) -> Path:
    """Nano with one weight changed (conftest `perturbed_nano`)."""
    return perturbed_nano


def test_the_export_records_the_weights_sha256_in_the_manifest_and_every_graph(nano_export):
    expected = reference_sha256(load_model(NANO))
    manifest = json.loads((nano_export / "engine.json").read_text())
    assert manifest["weights_sha256"] == expected and weights_sha256(load_model(NANO)) == expected
    assert manifest["source"] == str(NANO.resolve()) and set(manifest["files"]) == {"fp32"}
    import onnx

    for name in ("encoder.onnx", "head.onnx"):
        props = {p.key: p.value for p in onnx.load(str(nano_export / name), load_external_data=False).metadata_props}
        assert props["weights_sha256"] == expected


def test_other_weights_of_the_same_architecture_are_refused_naming_both_digests(nano_export, perturbed, tmp_path, capsys):
    exported, other = reference_sha256(load_model(NANO)), reference_sha256(load_model(perturbed))
    assert exported != other
    with pytest.raises(UserError) as refused:
        StreamingEngine(load_model(perturbed), EngineSetting(runtime="onnx"), onnx_dir=nano_export)
    assert str(refused.value) == (f"{nano_export}: the ONNX graphs were exported from other weights (sha256 "
                                  f"{exported[:12]}… ≠ this model's {other[:12]}…); export again with "
                                  "`touchanything export-onnx`")
    episode = write_episode(tmp_path / "ep", frames=12)
    assert main(["replay", str(episode), "--headless", "--onnx", str(nano_export), "--checkpoint", str(perturbed),
                 "--out", str(tmp_path / "out.mp4")]) == 2
    assert one_error_line(capsys) == f"touchanything replay: error: {refused.value}"
    assert not (tmp_path / "out.mp4").exists()


def test_the_same_weights_saved_again_are_accepted(nano_export, tmp_path):
    """The digest is of the weights, not of the checkpoint file: a re-saved copy runs the export."""
    save_checkpoint(tmp_path / "best_model.pth", load_model(NANO), epoch=7)
    assert (tmp_path / "best_model.pth").read_bytes() != NANO.read_bytes()
    StreamingEngine(load_model(tmp_path / "best_model.pth"), EngineSetting(runtime="onnx"), onnx_dir=nano_export)


def test_old_exports_and_foreign_graph_files_are_refused(nano_export, perturbed_nano_export, tmp_path):
    old = tmp_path / "old"
    shutil.copytree(nano_export, old)
    manifest = json.loads((old / "engine.json").read_text())
    del manifest["weights_sha256"]
    (old / "engine.json").write_text(json.dumps(manifest))
    with pytest.raises(UserError, match=r"does not record the SHA-256 of its weights .*export again"):
        StreamingEngine(load_model(NANO), EngineSetting(runtime="onnx"), onnx_dir=old)
    mixed = shutil.copytree(perturbed_nano_export, tmp_path / "mixed")
    shutil.copy(nano_export / "head.onnx", mixed / "head.onnx")
    with pytest.raises(UserError, match=r"head\.onnx: this graph was not exported with the weights"):
        OnnxRuntime(mixed)


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def add_user_files(folder: Path) -> dict[Path, str]:
    """A user's files beside an export: a note and a run log in a sub-folder; returns their SHA-256."""
    (folder / "my_notes.txt").write_text("notes of mine\n")
    (folder / "my_runs").mkdir()
    (folder / "my_runs" / "run1.csv").write_text("frame,score\n0,0.5\n")
    return {path: sha256(path) for path in (folder / "my_notes.txt", folder / "my_runs" / "run1.csv")}


EXPORT = ["encoder.onnx", "engine.json", "head.onnx"]


def test_exporting_again_replaces_only_the_exports_files(perturbed_nano_export, tmp_path, capsys):
    """The user's files in an earlier export's folder survive byte for byte, the earlier export's int8
    graphs the new one does not write are removed and named, and a symbolic link at a graph's name is replaced,
    not written through."""
    out = shutil.copytree(perturbed_nano_export, tmp_path / "graphs")  # an export of other weights, with int8
    kept = add_user_files(out)
    elsewhere = tmp_path / "elsewhere.onnx"
    elsewhere.write_bytes(b"a graph of mine, outside the folder")
    (out / "encoder.onnx").unlink()
    (out / "encoder.onnx").symlink_to(elsewhere)
    kept[elsewhere] = sha256(elsewhere)
    assert main(["export-onnx", "--checkpoint", str(NANO), "--out", str(out)]) == 0
    assert capsys.readouterr().err.strip() == (f"removed {out / 'encoder.int8.onnx'}, {out / 'head.int8.onnx'}: listed "
                                               "by the earlier export, not written by this one")
    assert sorted(p.name for p in out.iterdir()) == [*EXPORT, "my_notes.txt", "my_runs"]  # no temporary file left
    assert {path: sha256(path) for path in kept} == kept and not (out / "encoder.onnx").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["elsewhere.onnx", "graphs"]
    assert json.loads((out / "engine.json").read_text())["weights_sha256"] == reference_sha256(load_model(NANO))
    StreamingEngine(load_model(NANO), EngineSetting(runtime="onnx"), onnx_dir=out)


def test_a_folder_without_an_export_is_written_into_only_with_overwrite_and_keeps_its_files(tmp_path, capsys):
    """A non-empty folder that holds no export is refused; with --overwrite the export's files are written beside
    the user's, and a hard link at a graph's name is replaced, its other name (outside the folder) left intact."""
    out = tmp_path / "notes"
    out.mkdir()
    kept = add_user_files(out)
    elsewhere = tmp_path / "elsewhere.onnx"
    elsewhere.write_bytes(b"a graph of mine, outside the folder")
    (out / "encoder.onnx").hardlink_to(elsewhere)
    kept[elsewhere] = sha256(elsewhere)
    assert main(["export-onnx", "--checkpoint", str(NANO), "--out", str(out)]) == 2
    assert one_error_line(capsys) == (f"touchanything export-onnx: error: {out}: folder is not empty and holds no "
                                      "earlier export; pass --overwrite to write the export's files into it (nothing "
                                      "else there is removed)")
    assert sorted(p.name for p in out.iterdir()) == ["encoder.onnx", "my_notes.txt", "my_runs"]
    assert main(["export-onnx", "--checkpoint", str(NANO), "--out", str(out), "--overwrite"]) == 0
    assert "removed" not in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == [*EXPORT, "my_notes.txt", "my_runs"]
    assert {path: sha256(path) for path in kept} == kept and elsewhere.stat().st_nlink == 1
    StreamingEngine(load_model(NANO), EngineSetting(runtime="onnx"), onnx_dir=out)


def test_an_input_or_a_foreign_file_at_an_exports_name_is_refused_before_any_work(nano_export, perturbed, tmp_path,
                                                                                  capsys):
    """Refused before a model is loaded: an input at one of the export's names (even with --overwrite, also one
    an earlier manifest lists), a file the earlier export does not list (without --overwrite), the checkpoint's
    own folder (it holds no export). The manifest's names count only as entries directly in the folder."""
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "encoder.onnx").hardlink_to(perturbed)
    listed = shutil.copytree(nano_export, tmp_path / "listed")
    (listed / "old.onnx").hardlink_to(perturbed)
    manifest = json.loads((listed / "engine.json").read_text())
    manifest["files"]["int8"] = {"encoder": "old.onnx", "head": "../elsewhere.onnx"}
    (listed / "engine.json").write_text(json.dumps(manifest))
    assert earlier_files(listed) == {"encoder.onnx", "engine.json", "head.onnx", "old.onnx"}
    foreign = shutil.copytree(nano_export, tmp_path / "foreign")
    (foreign / "head.int8.onnx").write_text("mine")
    before = {path: sha256(path) for path in [*tmp_path.rglob("*"), *perturbed.parent.iterdir()] if path.is_file()}
    for extra, line in [
        (["--out", str(linked), "--overwrite"], f"{linked / 'encoder.onnx'}: is the input {perturbed} under another name"),
        (["--out", str(listed)], f"{listed / 'old.onnx'}: is the input {perturbed} under another name"),
        (["--out", str(foreign), "--int8"], f"{foreign / 'head.int8.onnx'}: exists; pass --overwrite to replace it"),
        (["--out", str(perturbed.parent)], f"{perturbed.parent}: folder is not empty and holds no earlier export"),
    ]:
        assert main(["export-onnx", "--checkpoint", str(perturbed), *extra]) == 2
        assert one_error_line(capsys).startswith(f"touchanything export-onnx: error: {line}")
    assert {path: sha256(path) for path in [*tmp_path.rglob("*"), *perturbed.parent.iterdir()] if path.is_file()} == before


def test_an_export_that_fails_leaves_the_folder_as_it_was(perturbed_nano_export, tmp_path):
    """The graphs and engine.json are renamed into place only once all are written: a write that fails (files may
    not grow past 64 kB in the process: EFBIG, as a full disk's ENOSPC) leaves every file of the earlier export
    (and the user's) as it was, and no temporary file."""
    out = shutil.copytree(perturbed_nano_export, tmp_path / "graphs")
    add_user_files(out)
    before = {path: sha256(path) for path in out.rglob("*") if path.is_file()}
    run = limited_run(["export-onnx", "--checkpoint", str(NANO), "--out", str(out)], max_bytes=64_000)
    assert run.returncode == 2, run.stderr
    assert run.stderr.strip() == (f"touchanything export-onnx: error: {out / 'encoder.onnx'}: not written (File too "
                                  "large)")
    assert {path: sha256(path) for path in out.rglob("*") if path.is_file()} == before


def test_the_user_cache_is_keyed_by_the_weights_filled_once_and_a_running_engine_is_left_alone(
        nano_export, perturbed, tmp_path, monkeypatch):
    """A cache folder of the model's digest that holds other graphs (here: nano's) is exported again, once: the
    next engine of those weights runs the cached graphs. The export happens while another engine runs on its
    thread, as on the dashboard's first switch to an ONNX tier: in this process torch's exporter traced that
    engine's module calls too and broke its step; the export runs in a child process now, and the running
    engine keeps predicting."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    model = load_model(perturbed)
    digest = reference_sha256(model)
    folder = onnx_cache_dir(digest)
    assert folder == tmp_path / "touchanything" / "onnx" / digest[:16]
    shutil.copytree(nano_export, folder)
    rng = np.random.default_rng(0)
    images = {v: rng.integers(0, 256, (64, 64, 3), dtype=np.uint8) for v in VIEW_NAMES}
    joints = (rng.normal(0, 2, (42, 3)) + [0, 0, 40]).astype(np.float32)
    done = threading.Event()
    with LiveEngine(StreamingEngine(load_model(NANO), EngineSetting())) as live:
        def feed() -> None:
            for i in itertools.count():
                if done.wait(1 / 30):
                    return
                live.submit(Snapshot(i, int(time.monotonic() * 1e6), images, joints, np.array([True, True])))

        feeder = threading.Thread(target=feed)
        feeder.start()
        try:
            started = live.stats.processed
            with ExportNiceness() as niceness:  # loaded off the main thread, as the dashboard's loader does
                loader = threading.Thread(target=StreamingEngine, args=(model, EngineSetting(runtime="onnx", precision="int8")))
                loader.start()
                loader.join()
            during = live.stats.processed - started
        finally:
            done.set()
            feeder.join()
    assert live.error is None and during >= 30
    assert niceness.seen == {os.nice(0) + 12}, niceness.seen  # the child below the engine (nice +8)
    manifest = json.loads((folder / "engine.json").read_text())
    assert manifest["weights_sha256"] == digest and set(manifest["files"]) == {"fp32", "int8"}
    stamp = (folder / "engine.json").stat().st_mtime_ns
    StreamingEngine(model, EngineSetting(runtime="onnx"))
    assert (folder / "engine.json").stat().st_mtime_ns == stamp


class ExportNiceness:
    """While open, watches for the cache's export child (`python -m ...onnx_cache`) and records the last nice value
    read of each (`seen`; a child starts at its parent's and nices itself first thing)."""

    def __enter__(self) -> ExportNiceness:
        self.last: dict[str, int] = {}
        self._stop = threading.Event()
        self._watcher = threading.Thread(target=self._watch)
        self._watcher.start()
        return self

    def _watch(self) -> None:
        while not self._stop.wait(0.05):
            for proc in Path("/proc").glob("[0-9]*"):
                try:
                    if b"touchanything.inference.engine.onnx_cache" in (proc / "cmdline").read_bytes():
                        self.last[proc.name] = int((proc / "stat").read_text().rsplit(")", 1)[1].split()[16])
                except (OSError, IndexError, ValueError):
                    continue

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._watcher.join()

    @property
    def seen(self) -> set[int]:
        return set(self.last.values())


def test_a_command_waiting_for_the_export_runs_it_at_its_own_priority_and_says_so(perturbed, tmp_path, monkeypatch,
                                                                                    capfd):
    """A headless command builds its engine on the main thread: nothing runs beside it, so the export child keeps
    the command's priority (a niced export of pico sat minutes on a busy machine) and the wait is said."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    with ExportNiceness() as niceness:
        StreamingEngine(load_model(perturbed), EngineSetting(runtime="onnx", precision="int8"))
    assert niceness.seen <= {os.nice(0)} and niceness.seen, niceness.seen  # seen at least once, never niced
    err = capfd.readouterr().err
    assert "exporting the ONNX graphs (first use) into " + str(tmp_path / "touchanything" / "onnx") in err
    assert err.rstrip().endswith(" s")


def test_a_failed_cache_export_is_one_line(tmp_path, monkeypatch):
    (tmp_path / "cache").write_text("a file where the cache folder would go")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    model = load_model(NANO)
    with pytest.raises(UserError) as refused:
        StreamingEngine(model, EngineSetting(runtime="onnx"))
    folder = tmp_path / "cache" / "touchanything" / "onnx" / reference_sha256(model)[:16]
    assert str(refused.value) == (f"{folder}: exporting the ONNX graphs into the cache failed: cannot be created "
                                  f"({tmp_path / 'cache'} is not a folder)")


def test_replay_runs_an_export_folder_and_names_it(nano_export, tmp_path, capsys):
    episode = write_episode(tmp_path / "ep", frames=12)
    out = tmp_path / "replay.mp4"
    assert main(["replay", str(episode), "--headless", "--onnx", str(nano_export), "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    model = next(line for line in lines if line.startswith("model "))
    assert f"(onnx-fp32 from {nano_export} on cpu)" in model and model.startswith("model     nano")
    assert out.is_file()


@pytest.mark.parametrize("extra, words", [
    (["--runtime", "torch"], "an ONNX export runs on the onnx runtime, not torch"),
    (["--precision", "int8"], "no int8 graphs; export with `touchanything export-onnx --int8`"),
    (["--setting", "nano/onnx-int8/all"], "drop --onnx"),
])
def test_replay_onnx_errors_are_one_line(nano_export, tmp_path, capsys, extra, words):
    episode = write_episode(tmp_path / "ep", frames=4)
    assert main(["replay", str(episode), "--headless", "--onnx", str(nano_export), "--out", str(tmp_path / "o.mp4"),
                 *extra]) == 2
    assert words in one_error_line(capsys)


def test_an_onnx_folder_without_manifest_is_one_line(tmp_path, capsys):
    assert main(["demo", "--headless", "--onnx", str(tmp_path), "--out", str(tmp_path / "demo.mp4")]) == 2
    assert one_error_line(capsys) == (f"touchanything demo: error: {tmp_path}: no engine.json; create the folder with "
                                      "`touchanything export-onnx`")


def test_live_and_scenes_take_an_export_folder(nano_export, tmp_path):
    session = open_live_session(SCENES / "sim.toml", device="cpu", onnx=nano_export)  # not started: no devices
    assert session.choice.onnx_dir == nano_export and session.choice.checkpoint == NANO.resolve()
    assert session.live.engine.runtime.name == "onnx" and f"from {nano_export}" in session.state().model
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[model]\nonnx_dir = "{nano_export}"\nprecision = "fp32"\n')
    choice = read_scene(scene).model
    assert (choice.setting.runtime, choice.onnx_dir, choice.checkpoint) == ("onnx", nano_export, NANO.resolve())
    scene.write_text(f'[model]\nonnx_dir = "{nano_export}"\nruntime = "torch"\n')
    with pytest.raises(UserError, match="runs on the onnx runtime, not torch"):
        read_scene(scene)

