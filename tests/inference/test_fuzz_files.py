"""Fuzzed model and scene files: a corrupted `config.yaml`, scene file or checkpoint gives one line naming the
file (or still loads); never an unhandled exception, never a hang. The corruptions are in
tests/helpers/fuzzing.py."""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from helpers.fuzzing import NANO, ROOT, corrupt_text, fraction, fuzz, no_hang
from touchanything.core.errors import UserError


@fuzz(80)
@given(st.data())
def test_a_corrupted_model_config_gives_one_line_naming_it(tmp_path_factory, data) -> None:
    from touchanything.inference.model.checkpoint import load_model

    folder = Path(tempfile.mkdtemp(prefix="fuzz-config-"))
    try:
        shutil.copyfile(NANO / "config.yaml", folder / "config.yaml")
        corrupt_text(folder / "config.yaml", data.draw)
        with no_hang():
            try:
                load_model(NANO / "best_model.pth", folder / "config.yaml")
            except UserError as exc:
                message = str(exc)
                assert "\n" not in message and ("config.yaml" in message or "best_model.pth" in message), message
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@fuzz(150)
@given(st.sampled_from(sorted((ROOT / "scenes").glob("*.toml"))), st.data())
def test_a_corrupted_scene_file_gives_one_line_naming_it(scene, data) -> None:
    from touchanything.app.sessions.scene import read_scene

    folder = Path(tempfile.mkdtemp(prefix="fuzz-scene-"))
    try:
        path = folder / scene.name
        shutil.copyfile(scene, path)
        corrupt_text(path, data.draw)
        with no_hang():
            try:
                read_scene(path)
            except UserError as exc:
                assert str(exc).startswith(str(path)) and "\n" not in str(exc), str(exc)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@fuzz(50)
@given(st.data())
def test_a_corrupted_checkpoint_gives_one_line_naming_it(data) -> None:
    from touchanything.inference.model.checkpoint import load_model

    folder = Path(tempfile.mkdtemp(prefix="fuzz-ckpt-"))
    try:
        path = folder / "best_model.pth"
        shutil.copyfile(NANO / "best_model.pth", path)
        raw = path.read_bytes()
        if data.draw(st.booleans(), label="truncate"):
            path.write_bytes(raw[:fraction(raw, data.draw(st.floats(0, 1)))])
        else:
            out = bytearray(raw)
            for f in data.draw(st.lists(st.floats(0, 1), min_size=1, max_size=4)):
                out[fraction(raw, f)] ^= data.draw(st.integers(1, 255))
            path.write_bytes(bytes(out))
        with no_hang():
            try:
                load_model(path, NANO / "config.yaml")
            except UserError as exc:
                assert str(exc).startswith(str(path)) and "\n" not in str(exc), str(exc)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
