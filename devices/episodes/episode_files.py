"""The non-video, non-JSONL files of a raw EgoTouch episode: pressure grids, masks, quality, intrinsics."""
from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.core.errors import DataError, describe
from touchanything.core.json_files import read_json_file
from touchanything.core.snapshot import HANDS

GRID_KEYS = ("left_pressure_grid", "right_pressure_grid")
MAXIMA_KEYS = ("tactile_max_left", "tactile_max_right", "bend_max_left", "bend_max_right")
SCALAR_KEYS = (*MAXIMA_KEYS, "grid_size", "num_frames", "separate_normalization", "normalized",
               "baseline_corrected_left", "baseline_corrected_right")
"""The scalars stored beside the grids (npz arrays, HDF5 `pressure` attributes): numbers or true/false."""


@dataclass
class PressureFile:
    """grids: (T, 2, 21, 21) float32 [left, right], NaN outside the layout; attrs: the npz scalars."""

    grids: np.ndarray
    attrs: dict = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)


def scalar_attrs(found: dict) -> tuple[dict, list[str]]:
    """The values of `found` that are single finite numbers or booleans, as Python scalars, and the names of
    the known scalars (`SCALAR_KEYS`) that are not (other names of another kind are left out silently)."""
    attrs, dropped = {}, []
    for key, value in found.items():
        try:
            array = np.asarray(value)
            ok = array.ndim == 0 and array.dtype.kind in "biuf" and bool(np.isfinite(array))
        except (TypeError, ValueError):
            ok = False
        if ok:
            attrs[key] = array.item()
        elif key in SCALAR_KEYS:
            dropped.append(key)
    return attrs, dropped


def range_problem(grids: np.ndarray) -> str | None:
    """What is wrong when pressure values (NaN = outside the layout) leave [0, 1], or None."""
    values = np.asarray(grids, np.float64)
    outside = ~np.isnan(values) & ((values < 0) | (values > 1))
    if not outside.any():
        return None
    bad = values[outside]
    return (f"{int(outside.sum())} value(s) outside [0, 1] (from {bad.min():.4g} to {bad.max():.4g}); "
            "metrics divide the trajectory by its maximum (the official fallback)")


def grids_normalized(grids: np.ndarray) -> bool:
    """Whether pressure grids (NaN = outside the layout) are stored normalised: every value in [0, 1] (the HDF5
    attribute `pressure.normalized` that `convert` writes)."""
    return bool(np.nanmax(grids, initial=0.0) <= 1.0 and np.nanmin(grids, initial=0.0) >= 0.0)


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as data:
            return {key: data[key] for key in data.files}
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except Exception as exc:  # zipfile, zlib and numpy's header parser raise a dozen types for damaged bytes
        # (BadZipFile, zlib.error, NotImplementedError for a compression method, TokenError, MemoryError for a
        # header claiming a huge shape, ...): each is the same "not readable" to the user
        reason = str(exc).splitlines()[0] if str(exc).strip() else exc.__class__.__name__
        raise DataError(path, None, f"not a readable .npz file ({reason})") from None


def _require(path: Path, data: dict, key: str, ndim: int, kinds: str) -> np.ndarray:
    if key not in data:
        raise DataError(path, key, "missing array")
    array = data[key]
    if array.ndim != ndim or array.dtype.kind not in kinds:
        raise DataError(path, key, f"has shape {array.shape} and dtype {array.dtype}, expected {ndim} dims of kind {kinds!r}")
    return array


def read_pressure_grids(path: Path) -> PressureFile:
    """Read `pressure_grids.npz` (official layout); checks shapes and dtypes."""
    data = _load_npz(path)
    left = _require(path, data, GRID_KEYS[0], 3, "f")
    right = _require(path, data, GRID_KEYS[1], 3, "f")
    for key, grid in zip(GRID_KEYS, (left, right)):
        if grid.shape[1:] != (21, 21):
            raise DataError(path, key, f"has shape {grid.shape}, expected (T, 21, 21)")
    if left.shape[0] != right.shape[0]:
        raise DataError(path, GRID_KEYS[1], f"has {right.shape[0]} frames but {GRID_KEYS[0]} has {left.shape[0]}")
    attrs, dropped = scalar_attrs({key: value for key, value in data.items() if key not in GRID_KEYS})
    problems = [describe(path, key, "expected a single number or true/false; ignored") for key in dropped]
    grids = np.stack([left, right], axis=1).astype(np.float32)
    if problem := range_problem(grids):
        problems.append(describe(path, "grids", problem))
    return PressureFile(grids, attrs, problems)


def save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Compressed .npz like `np.savez_compressed`, but byte-identical for identical arrays (fixed zip
    timestamps), so the same simulation seed gives the same files."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for key, value in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            with archive.open(info, "w", force_zip64=True) as handle:
                np.lib.format.write_array(handle, np.asanyarray(value), allow_pickle=False)


def write_pressure_grids(path: Path, grids: np.ndarray, baseline_applied: np.ndarray | None = None,
                         tactile_max: np.ndarray | None = None, bend_max: np.ndarray | None = None) -> None:
    """Write (T, 2, 21, 21) grids in the official npz layout; maxima given → separate_normalization."""
    grids = np.asarray(grids, np.float32)
    out: dict[str, np.ndarray] = {
        GRID_KEYS[0]: grids[:, 0], GRID_KEYS[1]: grids[:, 1],
        "grid_size": np.int64(21), "num_frames": np.int64(grids.shape[0]),
        "separate_normalization": np.bool_(tactile_max is not None),
    }
    if tactile_max is not None and bend_max is not None:
        for h, hand in enumerate(HANDS):
            out[f"tactile_max_{hand}"] = np.float64(tactile_max[h])
            out[f"bend_max_{hand}"] = np.float64(bend_max[h])
    if baseline_applied is not None:
        for h, hand in enumerate(HANDS):
            out[f"baseline_corrected_{hand}"] = np.bool_(baseline_applied[h])
    save_npz(path, out)


@dataclass
class Masks:
    """masks: (T, N, H, W) uint8; obj_ids: (T, N) int32; valid_frames: (T,) bool."""

    masks: np.ndarray
    obj_ids: np.ndarray
    valid_frames: np.ndarray


def read_masks(path: Path) -> Masks:
    """Read `masks.npz` (official keys masks, obj_ids, valid_frames)."""
    data = _load_npz(path)
    masks = _require(path, data, "masks", 4, "ub")
    obj_ids = _require(path, data, "obj_ids", 2, "iu")
    valid = _require(path, data, "valid_frames", 1, "b")
    if not (masks.shape[0] == obj_ids.shape[0] == valid.shape[0]) or masks.shape[1] != obj_ids.shape[1]:
        raise DataError(path, "masks", f"shapes disagree: masks {masks.shape}, obj_ids {obj_ids.shape}, valid_frames {valid.shape}")
    return Masks(masks.astype(np.uint8), obj_ids.astype(np.int32), valid.astype(bool))


def read_quality(path: Path) -> dict[str, float]:
    """`quality_issues.json` → {"left": ratio, "right": ratio} of duplicate wrist frames (−1 if unknown)."""
    data = read_json_file(path)
    ratios = {}
    for side in HANDS:
        try:
            ratios[side] = float(data["duplicate_frames"][side]["ratio"])
        except (TypeError, KeyError, ValueError, OverflowError):
            ratios[side] = -1.0
    return ratios


def read_camera_matrices(path: Path) -> dict[str, np.ndarray]:
    """`camera_matrix.txt` → {camera: (3, 3) float64}.

    The file holds one or more 3×3 matrices, each after a `# <camera>` line (chest, left, right); a bare
    3×3 matrix without a name is the chest camera's.
    """
    try:
        lines = Path(path).read_text().splitlines()
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(path, None, f"not a readable text file ({exc})") from None
    blocks: dict[str, list[list[float]]] = {}
    name = "chest"
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if text.startswith("#"):
            name = text.lstrip("#").strip()
        elif text:
            try:
                blocks.setdefault(name, []).append([float(v) for v in text.split()])
            except ValueError:
                raise DataError(path, f"line {number}", "expected numbers") from None
    matrices = {}
    for camera, rows in blocks.items():
        matrix = np.array(rows, dtype=np.float64) if all(len(r) == 3 for r in rows) else None
        if matrix is None or matrix.shape != (3, 3) or not np.all(np.isfinite(matrix)):
            raise DataError(path, camera, "expected a 3×3 matrix of finite numbers")
        matrices[camera] = matrix
    return matrices


def write_camera_matrices(path: Path, matrices: dict[str, np.ndarray]) -> None:
    with open(path, "w") as handle:
        for camera, matrix in matrices.items():
            handle.write(f"# {camera}\n")
            np.savetxt(handle, np.asarray(matrix, np.float64), fmt="%.9g")
