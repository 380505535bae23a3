"""Shared by the fuzzed-reader properties (tests/devices/test_fuzz_episodes.py, tests/inference/test_fuzz_files.py):
hypothesis settings, the guards that turn a hang or a traceback into a failure, and the corruptions — one edit of
one file (truncation, byte flips, a deleted byte range, a JSON-lines line replaced by random JSON or a line break
moved, an npz array or HDF5 dataset of another shape or dtype, flipped bytes inside an HDF5 dataset's storage).

`FUZZ_EXAMPLES=10 pytest tests/*/test_fuzz_*.py` multiplies the number of examples (a longer hunt).
"""
from __future__ import annotations

import contextlib
import faulthandler
import io
import json
import os
import signal
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from touchanything.app.cli import main
from touchanything.devices.episodes.episode_files import save_npz
from touchanything.devices.episodes.raw_episode import (
    GLOVE_FILE,
    GRIDS_FILE,
    MASKS_FILE,
    ROKOKO_FILE,
    VIDEO_FILES,
    VIVE_FILE,
    WILOR_FILE,
)

ROOT = Path(__file__).resolve().parents[2]
NANO = ROOT / "models" / "nano"
FRAMES = 8
"""Frames of the fuzzed episode."""
SCALE = int(os.environ.get("FUZZ_EXAMPLES", "1"))
STEP_SECONDS = 60
"""A single command on a corrupted file taking longer than this is a hang."""

JSONL_FILES = (WILOR_FILE, ROKOKO_FILE, VIVE_FILE, GLOVE_FILE)
RAW_FILES = (*VIDEO_FILES.values(), GRIDS_FILE, MASKS_FILE, *JSONL_FILES, "quality_issues.json", "camera_matrix.txt")


def fuzz(examples: int) -> settings:
    """Hypothesis settings of these properties: `examples` (times FUZZ_EXAMPLES), no deadline."""
    return settings(max_examples=examples * SCALE, deadline=None, suppress_health_check=list(HealthCheck), database=None)


# ---------------------------------------------------------------------------------------------- guards

class Hang(Exception):
    pass


@contextlib.contextmanager
def no_hang(seconds: int = STEP_SECONDS):
    """A Python-level hang raises Hang; one stuck in C code ends the process with every thread's traceback."""
    def alarm(signum, frame):
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    faulthandler.dump_traceback_later(seconds * 3, exit=True)
    try:
        yield
    finally:
        signal.alarm(0)
        faulthandler.cancel_dump_traceback_later()
        signal.signal(signal.SIGALRM, previous)


@dataclass
class Outcome:
    code: int
    out: str
    err: str


def cli(*argv: str) -> Outcome:
    """`touchanything ARGV` in this process, output captured; an unhandled exception fails the test."""
    out, err = io.StringIO(), io.StringIO()
    with no_hang(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return Outcome(code, out.getvalue(), err.getvalue())


def assert_one_error_line(outcome: Outcome, command: str, names: str | None = None) -> str:
    """Exit 2 and exactly one `touchanything COMMAND: error: …` line on stderr (progress bars aside)."""
    assert outcome.code == 2, outcome
    assert "Traceback" not in outcome.err
    errors = [line for line in outcome.err.splitlines() if "error:" in line]
    assert len(errors) == 1 and errors[0].startswith(f"touchanything {command}: error: "), outcome.err
    assert "\n" not in errors[0]
    if names is not None:
        assert names in errors[0], errors[0]
    return errors[0]


# ---------------------------------------------------------------------------------------------- corruptions

def _spans(data: bytes) -> list[tuple[int, int]]:
    """(start, end) of each line, its newline included."""
    spans, start = [], 0
    while start < len(data):
        end = data.find(b"\n", start)
        end = len(data) if end < 0 else end + 1
        spans.append((start, end))
        start = end
    return spans


@dataclass
class Corruption:
    """One edit of one file; `touched` is the byte range [lo, hi) of the original it changes (hi = None: to
    the end), `line` the replaced JSONL line, `array` / `dataset` the replaced npz array / HDF5 dataset."""

    name: str
    kind: str
    lo: int = 0
    hi: int | None = None
    line: int | None = None
    array: str | None = None
    dataset: str | None = None

    def frames_touched(self, original: bytes) -> set[int]:
        """JSONL frames this edit may change: the lines it touches and one line either side (a removed or
        added newline merges or splits lines); everything from the first one on for a truncation."""
        if self.line is not None:
            return {self.line}
        spans = _spans(original)
        hit = [i for i, (a, b) in enumerate(spans) if a < (self.hi if self.hi is not None else len(original)) and b > self.lo]
        if not hit:
            return set()
        last = len(spans) + FRAMES if self.hi is None else hit[-1] + 1
        return set(range(max(hit[0] - 1, 0), last + 1))


def fraction(data: bytes, f: float) -> int:
    return min(int(f * len(data)), max(len(data) - 1, 0))


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.sampled_from([2**63, -2**63 - 1, 10**400, -1, 255, 256])
    | st.floats() | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=25) | st.dictionaries(st.text(max_size=10), inner, max_size=5),
    max_leaves=60)


def _replace_somewhere(draw, value, depth: int = 0):
    """`value` with one node (perhaps itself) replaced by random JSON."""
    if depth > 4 or draw(st.integers(0, 3)) == 0:
        return draw(json_values)
    if isinstance(value, dict) and value:
        key = draw(st.sampled_from(sorted(value)))
        return {**value, key: _replace_somewhere(draw, value[key], depth + 1)}
    if isinstance(value, list) and value:
        i = draw(st.integers(0, len(value) - 1))
        return value[:i] + [_replace_somewhere(draw, value[i], depth + 1)] + value[i + 1:]
    return draw(json_values)


def _odd_array(draw, like: np.ndarray) -> np.ndarray:
    """An array of another shape and/or dtype than `like`."""
    shapes = [like.shape, (), (3,), like.shape + (1,), tuple(max(s - 1, 0) for s in like.shape)]
    if like.ndim:
        shapes += [like.shape[:-1], (like.shape[0] + 5,) + like.shape[1:], (0,) + like.shape[1:]]
    shape = draw(st.sampled_from(shapes))
    dtype = draw(st.sampled_from(["float32", "float64", "float16", "int32", "uint8", "bool", "complex64", "U3", "S2"]))
    if shape == like.shape and np.dtype(dtype) == like.dtype:
        shape = (3,)
    values = draw(st.sampled_from([0.0, 1.0, 7.5, float("nan"), float("inf")]))
    with np.errstate(invalid="ignore"):
        return np.full(shape, values).astype(dtype)


def apply(path: Path, draw, name: str, extra_kinds: tuple[str, ...] = ()) -> Corruption:
    """Corrupt `path` in place with one edit drawn by `draw`."""
    data = path.read_bytes()
    kind = draw(st.sampled_from(("delete_file", "truncate", "flip", "delete_range") + extra_kinds))
    if kind == "delete_file":
        path.unlink()
        return Corruption(name, kind, 0, None)
    if kind == "truncate":
        at = fraction(data, draw(st.floats(0, 1)))
        path.write_bytes(data[:at])
        return Corruption(name, kind, at, None)
    if kind == "flip":
        at = [fraction(data, f) for f in draw(st.lists(st.floats(0, 1), min_size=1, max_size=3))]
        span = (max(at) - min(at)) if len(data) else 0
        if span > 64:  # flips in one region, so a JSONL edit touches a few lines
            at = [at[0] + (a - at[0]) % 64 for a in at if at[0] + (a - at[0]) % 64 < len(data)]
        out = bytearray(data)
        for a in at:
            out[a] ^= draw(st.integers(1, 255))
        path.write_bytes(bytes(out))
        return Corruption(name, kind, min(at, default=0), max(at, default=0) + 1)
    if kind == "delete_range":
        lo = fraction(data, draw(st.floats(0, 1)))
        hi = min(lo + draw(st.integers(1, 300)), len(data))
        path.write_bytes(data[:lo] + data[hi:])
        return Corruption(name, kind, lo, hi)
    if kind == "line_break":  # a newline lost, a stray one, or a whole line gone: later lines move
        spans = _spans(data)
        i = draw(st.integers(0, len(spans) - 1))
        a, b = spans[i]
        how = draw(st.sampled_from(("join", "split", "drop")))
        at = b - 1 if how == "join" else a + draw(st.integers(0, b - a - 1)) if how == "split" else a
        path.write_bytes(data[:at] + (b"\n" if how == "split" else b"") + data[{"join": at + 1, "split": at, "drop": b}[how]:])
        return Corruption(name, kind, a, b)
    if kind == "hdf5_storage":  # flips inside one dataset's stored bytes (a chunk, or contiguous data)
        with h5py.File(path, "r") as file:
            keys = []
            file.visit(lambda k: keys.append(k) if isinstance(file[k], h5py.Dataset) and file[k].size else None)
            key = draw(st.sampled_from(sorted(keys)))
            dataset = file[key]
            if dataset.chunks:
                info = dataset.id.get_chunk_info(draw(st.integers(0, dataset.id.get_num_chunks() - 1)))
                start, size = info.byte_offset, info.size
            else:
                start, size = dataset.id.get_offset(), dataset.id.get_storage_size()
        out = bytearray(data)
        for f in draw(st.lists(st.floats(0, 1), min_size=1, max_size=4)):
            out[start + min(int(f * size), size - 1)] ^= draw(st.integers(1, 255))
        path.write_bytes(bytes(out))
        return Corruption(name, kind, dataset=key)
    if kind == "jsonl_line":
        lines = data.decode().splitlines()
        i = draw(st.integers(0, len(lines) - 1))
        whole = draw(st.booleans())
        value = draw(json_values) if whole else _replace_somewhere(draw, json.loads(lines[i]))
        lines[i] = json.dumps(value)
        path.write_text("\n".join(lines) + "\n")
        return Corruption(name, kind, line=i)
    if kind == "npz_array":
        with np.load(path) as npz:
            arrays = {k: npz[k] for k in npz.files}
        key = draw(st.sampled_from(sorted(arrays)))
        if draw(st.integers(0, 4)) == 0:
            del arrays[key]
        else:
            arrays[key] = _odd_array(draw, arrays[key])
        save_npz(path, arrays)
        return Corruption(name, kind, array=key)
    if kind == "hdf5_dataset":
        with h5py.File(path, "a") as file:
            keys = []
            file.visit(lambda k: keys.append(k) if isinstance(file[k], h5py.Dataset) else None)
            key = draw(st.sampled_from(sorted(keys)))
            like = file[key][()]
            del file[key]
            if draw(st.integers(0, 4)):
                odd = _odd_array(draw, np.asarray(like))
                file.create_dataset(key, data=odd.astype("S") if odd.dtype.kind == "U" else odd)
        return Corruption(name, kind, dataset=key)
    raise AssertionError(kind)


def corrupt_text(path: Path, draw) -> None:
    """Truncate, flip bytes, delete a range, or replace one line with random JSON (valid YAML and TOML-ish)."""
    kind = draw(st.sampled_from(("truncate", "flip", "delete_range", "line")))
    if kind == "line":
        lines = path.read_text().splitlines() or [""]
        i = draw(st.integers(0, len(lines) - 1))
        keep = lines[i].split("=", 1)[0] + "= " if "=" in lines[i] else lines[i].split(":", 1)[0] + ": "
        lines[i] = (keep if draw(st.booleans()) else "") + json.dumps(draw(json_values))
        path.write_text("\n".join(lines) + "\n")
    else:
        apply(path, draw, path.name)
