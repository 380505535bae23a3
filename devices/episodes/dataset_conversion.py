"""Convert a whole raw EgoTouch root to HDF5 with worker processes, and write the two reports."""
from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from touchanything.core.errors import DataError, UserError, failure_line
from touchanything.core.output_safety import check_outside, check_report_folder, write_text
from touchanything.devices.episodes.dataset_split import SPLIT_FILE, SPLIT_KEYS, read_split, write_split
from touchanything.devices.episodes.episode_loader import find_raw_episodes
from touchanything.devices.episodes.hdf5_convert import ConversionResult, convert_trajectory, output_path, source_name
from touchanything.devices.episodes.hdf5_output import written_from

CONVERSION_REPORT = "conversion_report.txt"
QUALITY_REPORT = "quality_report.txt"


def convert_dataset(raw_root: Path, out_root: Path, workers: int = 1, compression_level: int = 4,
                    skip_existing: bool = False,
                    on_result: Callable[[ConversionResult], None] | None = None,
                    on_start: Callable[[int], None] | None = None, overwrite: bool = False,
                    on_note: Callable[[str], None] | None = None) -> list[ConversionResult]:
    """Convert every trajectory under `raw_root`; one bad trajectory never stops the others. `on_start(n)`:
    once the inputs and outputs were checked, with the number of trajectories found; `on_note(line)`: what the
    carried-over `split.json` left out (`carried_split`), before it is written. An existing trajectory is
    replaced (or with `skip_existing` left alone) only when this project converted it from the same episode
    (`hdf5_output`'s mark), a report only when this project wrote it (`output_safety.named`); anything else at a target path is refused
    before any work unless `overwrite`. RAW's `split.json` is carried over listing only the trajectories OUT holds."""
    raw_root, out_root = Path(raw_root), Path(out_root)
    if not raw_root.is_dir():
        raise UserError(f"{raw_root}: raw root folder not found")
    if not 0 <= compression_level <= 9:
        raise UserError(f"--compression-level must be 0–9 (0 = none), got {compression_level}")
    if workers < 1:
        raise UserError(f"--workers must be at least 1, got {workers}")
    folders = find_raw_episodes(raw_root)
    if not folders:
        raise UserError(f"{raw_root}: no trajectories found (folders holding chest.mp4, up to 4 levels deep)")
    check_outside(out_root, folders)
    check_report_folder(out_root, (CONVERSION_REPORT, QUALITY_REPORT), (raw_root,), overwrite=overwrite)
    results, todo = plan(folders, raw_root, out_root, skip_existing, overwrite)
    on_start and on_start(len(folders))
    started = time.perf_counter()
    for result in results:
        on_result and on_result(result)
    for result in _run(todo, workers, compression_level):
        results.append(result)
        on_result and on_result(result)
    results.sort(key=lambda r: str(r.source))
    split, note = carried_split(raw_root, out_root, results)
    note and on_note and on_note(note)
    write_reports(out_root, results, time.perf_counter() - started, note)
    if split:
        write_split(out_root / SPLIT_FILE, split)
    return results


def plan(folders: list[Path], raw_root: Path, out_root: Path, skip_existing: bool,
         overwrite: bool) -> tuple[list[ConversionResult], list[tuple[Path, Path, str]]]:
    """(skipped results, (folder, target, source) to convert). UserError naming the first target that exists but
    is not this project's conversion of that episode (another file, a cut-short or another episode's
    trajectory), unless `overwrite`."""
    skipped, todo, foreign = [], [], []
    for folder in folders:
        target, source = output_path(folder, raw_root, out_root), source_name(folder, raw_root)
        ours = target.exists() and written_from(target) == source
        if ours and skip_existing:
            skipped.append(ConversionResult(folder, target, "skipped"))
            continue
        if target.exists() and not ours and not overwrite:
            foreign.append(target)
        todo.append((folder, target, source))
    if foreign:
        more = f" (and {len(foreign) - 1} more)" if len(foreign) > 1 else ""
        raise UserError(f"{foreign[0]}: exists and is not this project's conversion of that episode{more}; pass "
                        "--overwrite to replace it")
    return skipped, todo


def carried_split(raw_root: Path, out_root: Path,
                  results: list[ConversionResult]) -> tuple[dict[str, list[Path]] | None, str | None]:
    """A `split.json` shipped with the raw data moves into the HDF5 root (as the official release does), listing
    only the trajectories this run converted or found converted (`skipped`). Returns (that split, or None when
    there is none to write: none shipped, it would list none, or OUT holds one that is not an earlier carried
    copy (kept); what it left out as one line, or None)."""
    source, target = raw_root / SPLIT_FILE, out_root / SPLIT_FILE
    if not source.is_file():
        return None, None
    try:
        listed = read_split(source)
    except DataError as exc:
        return None, f"{exc}; not carried over"
    if target.exists() and not _carried_before(target, listed, raw_root, out_root):
        return None, None
    held = {r.output.relative_to(out_root) for r in results if r.status != "failed"}
    places = {key: [_under(e, raw_root) for e in listed[key]] for key in SPLIT_KEYS}
    split = {key: [out_root / p for p in places[key] if p in held] for key in SPLIT_KEYS}
    left_out = [p or e for key in SPLIT_KEYS for p, e in zip(places[key], listed[key]) if p not in held]
    kept = sum(map(len, split.values()))
    if not left_out:
        return split, None
    fate = f"{target} lists the other {kept}" if kept else f"{SPLIT_FILE} not written (it would list none)"
    return split if kept else None, (f"{source}: {len(left_out)} listed trajectory(ies) not in {out_root} (failed or "
                                     f"not found), the first {left_out[0]}; {fate}")


def _carried_before(target: Path, listed: dict[str, list[Path]], raw_root: Path, out_root: Path) -> bool:
    """OUT's split file is an earlier carried copy of RAW's: a plain file, each of its lists part of RAW's same list."""
    if not target.is_file():
        return False
    try:
        earlier = read_split(target)
    except DataError:
        return False
    return all({_under(e, out_root) for e in earlier[key]} <= {_under(e, raw_root) for e in listed[key]} for key in SPLIT_KEYS)


def _under(entry: Path, root: Path) -> Path | None:
    """A split entry's place under `root` (None when it lies elsewhere)."""
    relative = Path(os.path.relpath(entry, root))
    return None if relative.parts[:1] == ("..",) else relative


def _run(todo: list[tuple[Path, Path, str]], workers: int, level: int):
    if workers == 1 or len(todo) <= 1:
        for folder, target, source in todo:
            yield convert_trajectory(folder, target, level, source)
        return
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(convert_trajectory, folder, target, level, source): (folder, target)
                   for folder, target, source in todo}
        try:
            for future in as_completed(futures):
                try:
                    yield future.result()
                except Exception as exc:  # noqa: BLE001 - a worker that died (killed, out of memory) fails its trajectory
                    folder, target = futures[future]
                    yield ConversionResult(folder, target, "failed", error=failure_line(folder, exc))
        except BaseException:  # Ctrl-C, SIGTERM: no trajectory starts any more; the running ones end whole
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def summary_line(results: list[ConversionResult], wall_seconds: float) -> str:
    """Counts, then the speed twice, each labelled: frames per second of wall time (what the user waited) and
    per worker (frames over the work time summed over trajectories; lower with several workers)."""
    counts = {s: sum(r.status == s for r in results) for s in ("converted", "skipped", "failed")}
    damaged = sum(r.damage is not None for r in results)
    frames = sum(r.frames for r in results)
    work = sum(r.seconds for r in results)
    return (f"converted {counts['converted']}{f' ({damaged} damaged)' if damaged else ''}, skipped {counts['skipped']}, "
            f"failed {counts['failed']}; "
            f"{frames} frames in {wall_seconds:.1f} s wall time ({frames / wall_seconds if wall_seconds else 0:.1f} "
            f"frames/s), {work:.1f} s of work summed over trajectories ({frames / work if work else 0:.1f} frames/s "
            "per worker)")


def damaged_line(result: ConversionResult) -> str | None:
    """`damaged: OUT/…/001.hdf5: <what it lacks>` for a trajectory converted from an episode that is not whole."""
    return f"damaged: {result.output}: {result.damage}" if result.damage else None


def write_reports(out_root: Path, results: list[ConversionResult], wall_seconds: float, split_note: str | None) -> None:
    """`conversion_report.txt` (`summary_line`, then the status per trajectory, each damaged one's
    `damaged_line`, and what `split.json` left out) and `quality_report.txt` (problems and
    quality; ratios the raw folder does not give read "not measured")."""
    lines = [summary_line(results, wall_seconds), ""]
    for r in results:
        detail = r.error if r.status == "failed" else f"{r.frames} frames, {r.seconds:.1f} s of work"
        lines.append(f"{r.status:9s} {r.source} -> {r.output}: {detail}")
    lines += [line for r in results if (line := damaged_line(r))] + ([split_note] if split_note else [])
    write_text(out_root / CONVERSION_REPORT, "\n".join(lines) + "\n")
    quality = []
    for r in results:
        if r.status != "converted":
            continue
        q = r.quality
        quality.append(f"{r.output}: wilor valid {q.get('wilor_valid_ratio', 0):.1%}, "
                       f"{duplicate_frames(q.get('left', -1), q.get('right', -1))}")
        quality += [f"  problem: {p}" for p in r.problems]
    write_text(out_root / QUALITY_REPORT, "\n".join(quality) + "\n")


def duplicate_frames(left: float, right: float) -> str:
    """The wrist cameras' duplicate-frame ratios as text; a negative ratio (the official "unknown": no
    `quality_issues.json`) is not measured."""
    if left < 0 and right < 0:
        return "duplicate wrist frames not measured (no quality_issues.json)"
    return "duplicate wrist frames " + ", ".join(f"{hand} {ratio:.1%}" if ratio >= 0 else f"{hand} not measured"
                                                 for hand, ratio in (("left", left), ("right", right)))
