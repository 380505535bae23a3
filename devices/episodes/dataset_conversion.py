"""Convert a whole raw EgoTouch root to HDF5 with worker processes, and write the two reports."""
from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from touchanything.devices.episodes.dataset_split import SPLIT_FILE
from touchanything.devices.episodes.episode_loader import find_raw_episodes
from touchanything.devices.episodes.hdf5_convert import ConversionResult, convert_trajectory, output_path, source_name
from touchanything.devices.episodes.hdf5_output import written_from
from touchanything.devices.errors import UserError, failure_line
from touchanything.devices.output_safety import check_outside, check_report_folder, replacing, write_text

CONVERSION_REPORT = "conversion_report.txt"
QUALITY_REPORT = "quality_report.txt"


def convert_dataset(raw_root: Path, out_root: Path, workers: int = 1, compression_level: int = 4,
                    skip_existing: bool = False,
                    on_result: Callable[[ConversionResult], None] | None = None,
                    on_start: Callable[[int], None] | None = None, overwrite: bool = False) -> list[ConversionResult]:
    """Convert every trajectory under `raw_root`; one bad trajectory never stops the others. `on_start(n)`:
    once the inputs and outputs were checked, with the number of trajectories found. An existing trajectory is
    replaced (or with `skip_existing` left alone) only when this project converted it from the same episode
    (`hdf5_output`'s mark); anything else at a target path is refused before any work unless `overwrite`."""
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
    check_report_folder(out_root, (CONVERSION_REPORT, QUALITY_REPORT), (raw_root,))
    results, todo = plan(folders, raw_root, out_root, skip_existing, overwrite)
    on_start and on_start(len(folders))
    started = time.perf_counter()
    for result in results:
        on_result and on_result(result)
    for result in _run(todo, workers, compression_level):
        results.append(result)
        on_result and on_result(result)
    results.sort(key=lambda r: str(r.source))
    write_reports(out_root, results, time.perf_counter() - started)
    copy_split(raw_root, out_root)
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


def copy_split(raw_root: Path, out_root: Path) -> None:
    """A `split.json` shipped with the raw data moves into the HDF5 root (as the official release does);
    an existing one there is kept."""
    source, target = raw_root / SPLIT_FILE, out_root / SPLIT_FILE
    if source.is_file() and not target.exists():
        with replacing(target) as temporary:
            shutil.copyfile(source, temporary)


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
    frames = sum(r.frames for r in results)
    work = sum(r.seconds for r in results)
    return (f"converted {counts['converted']}, skipped {counts['skipped']}, failed {counts['failed']}; "
            f"{frames} frames in {wall_seconds:.1f} s wall time ({frames / wall_seconds if wall_seconds else 0:.1f} "
            f"frames/s), {work:.1f} s of work summed over trajectories ({frames / work if work else 0:.1f} frames/s "
            "per worker)")


def write_reports(out_root: Path, results: list[ConversionResult], wall_seconds: float) -> None:
    """`conversion_report.txt` (`summary_line`, then the status per trajectory) and `quality_report.txt`
    (problems, quality; ratios the raw folder does not give read "not measured")."""
    lines = [summary_line(results, wall_seconds), ""]
    for r in results:
        detail = r.error if r.status == "failed" else f"{r.frames} frames, {r.seconds:.1f} s of work"
        lines.append(f"{r.status:9s} {r.source} -> {r.output}: {detail}")
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
