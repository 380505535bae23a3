"""The speed/accuracy atlas read back (`bench`'s engine.json): each setting's held-out accuracy and the weights
it was measured with, and the choice a latency budget makes — the most accurate setting whose p99 latency,
measured on this machine by a short probe, fits the budget.

Accuracy comes from the atlas (it needs the held-out set and an hour); latency is probed here, because it is a
property of the machine. Settings are probed from the most accurate down and the first that fits is taken,
so a generous budget probes one setting; then a faster setting the atlas cannot tell apart from it (their
paired V-IoU difference on the same trajectories has a 95 % interval that holds 0) is preferred, the
fastest such one that fits. A model whose file here differs from the one the atlas measured
(`checkpoint_sha256`) makes the atlas unusable for it: the choice is refused rather than made on another
model's accuracy.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from touchanything.core.errors import UserError, require_finite_positive
from touchanything.core.snapshot import Snapshot
from touchanything.inference.engine.engine_setting import EngineSetting, parse_setting
from touchanything.inference.evaluation.bootstrap import Resampler

if TYPE_CHECKING:
    from touchanything.inference.model.models import TactileModel

PROBE_FRAMES = {True: 40, False: 150}
"""Frames timed per setting by the probe, --quick or not (after `PROBE_WARMUP` untimed ones)."""
PROBE_WARMUP = 10


@dataclass(frozen=True)
class AtlasRow:
    """One setting of the atlas: accuracy (mean over `trajectories` held-out trajectories, 95 % intervals) and
    the p99 latency measured where the atlas was made."""

    setting: EngineSetting
    checkpoint_sha256: str
    trajectories: int
    volumetric_iou: float
    volumetric_iou_ci95: tuple[float, float]
    contact_iou: float
    contact_iou_ci95: tuple[float, float]
    atlas_p99_ms: float
    per_trajectory_viou: tuple[float, ...] = ()
    """V-IoU per held-out trajectory, in `strata`'s order (NaN: not replayed); empty in an atlas without them."""
    strata: tuple[str, ...] = ()
    """The split of each trajectory of the atlas run (the bootstrap's strata)."""

    @property
    def name(self) -> str:
        return self.setting.name()

    def accuracy_line(self) -> str:
        """"V-IoU 0.552 [0.531, 0.573], C-IoU 0.661 [0.640, 0.680] on 108 held-out trajectories"."""
        v, c = self.volumetric_iou_ci95, self.contact_iou_ci95
        return (f"V-IoU {self.volumetric_iou:.3f} [{v[0]:.3f}, {v[1]:.3f}], C-IoU {self.contact_iou:.3f} "
                f"[{c[0]:.3f}, {c[1]:.3f}] on {self.trajectories} held-out trajectories")


def _row(entry: dict, strata: tuple[str, ...]) -> AtlasRow | None:
    """The AtlasRow of a bench row with accuracy and latency (None for a pose-only twin or a latency-only row)."""
    if entry.get("blank") or not isinstance(entry.get("volumetric_iou"), float) or entry.get("p99_ms") is None:
        return None
    values = tuple(float(x) for x in (entry.get("per_trajectory") or {}).get("volumetric_iou", ()))
    if values and len(values) != len(strata):
        raise ValueError(f"{entry['setting']}: {len(values)} per-trajectory values for {len(strata)} trajectories")
    return AtlasRow(parse_setting(entry["setting"]), str(entry["checkpoint_sha256"]), int(entry["trajectories"]),
                    float(entry["volumetric_iou"]), tuple(float(x) for x in entry["volumetric_iou_ci95"]),
                    float(entry["contact_iou"]), tuple(float(x) for x in entry["contact_iou_ci95"]), float(entry["p99_ms"]),
                    values, strata if values else ())


def read_atlas(path: Path) -> list[AtlasRow]:
    """The settings of a bench record with accuracy and latency; UserError (one line) for a missing or damaged
    file, or one without such settings."""
    path = Path(path)
    try:
        record = json.loads(path.read_text())
        strata = tuple(str(t["split"]) for t in record.get("trajectories") or ())
        rows = [row for entry in record["rows"] if (row := _row(entry, strata)) is not None]
    except FileNotFoundError:
        raise UserError(f"{path}: atlas not found (make one with `touchanything bench`)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read the atlas ({exc.strerror or exc})") from None
    except (ValueError, KeyError, TypeError, AttributeError, UserError) as exc:
        raise UserError(f"{path}: not a readable atlas (a `touchanything bench` engine.json): "
                        f"{type(exc).__name__} {exc}".rstrip()) from None
    if not rows:
        raise UserError(f"{path}: the atlas holds no setting with both accuracy and latency")
    return rows


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def rows_for(rows: list[AtlasRow], checkpoints: dict[str, Path], atlas: Path) -> list[AtlasRow]:
    """The atlas rows of the models present here (name → checkpoint), most accurate first (faster first among
    equals); UserError when a present model's weights are not the ones the atlas measured."""
    digests = {name: file_sha256(path) for name, path in checkpoints.items()
               if any(row.setting.model == name for row in rows)}
    for row in rows:
        here = digests.get(row.setting.model)
        if here is not None and here != row.checkpoint_sha256:
            raise UserError(f"{atlas}: measured with other weights of {row.setting.model} (sha256 "
                            f"{row.checkpoint_sha256[:12]}…, {checkpoints[row.setting.model]} is {here[:12]}…); "
                            "re-measure with `touchanything bench`")
    present = [row for row in rows if row.setting.model in digests]
    if not present:
        raise UserError(f"{atlas}: none of its models ({', '.join(sorted({r.setting.model for r in rows}))}) is here")
    return sorted(present, key=lambda row: (-row.volumetric_iou, row.atlas_p99_ms))


def find_row(rows: list[AtlasRow], name: str, atlas: Path) -> AtlasRow:
    """The row of the setting `name`; UserError listing a few names when the atlas has no such setting."""
    setting = parse_setting(name)
    for row in rows:
        if row.setting == dataclasses.replace(setting, device=row.setting.device):
            return row
    known = ", ".join(row.name for row in rows[:4])
    raise UserError(f"setting {name} is not in the atlas {atlas} (its most accurate: {known}, …)")


def probe_p99(model: TactileModel, setting: EngineSetting, clip: list[Snapshot], frames: int, device: str,
              checkpoint: Path | None = None) -> float:
    """p99 per-frame step time (ms) of `setting` on this machine over `frames` frames of `clip` (after
    PROBE_WARMUP untimed ones); ONNX graphs come from the user cache (exported on first use); an ensemble
    setting loads its members from beside `checkpoint`, the file `model` came from."""
    from touchanything.inference.engine.ensemble_engine import engine_for  # imported where used: --help loads this module

    engine = engine_for(model, checkpoint, dataclasses.replace(setting, device=device))
    times = []
    for i in range(PROBE_WARMUP + frames):
        snapshot = dataclasses.replace(clip[i % len(clip)], frame_index=i, t_us=int(time.monotonic() * 1e6))
        start = time.perf_counter()
        engine.step(snapshot)
        if i >= PROBE_WARMUP:
            times.append((time.perf_counter() - start) * 1000)
    return float(np.percentile(times, 99))


@dataclass(frozen=True)
class BudgetChoice:
    """The chosen row with its p99 measured here, every probe made (setting name → p99 ms), the more accurate
    settings not probed because their look-ahead alone exceeds the budget, and, when a faster setting was
    preferred to a more accurate one it cannot be told apart from, that one's name and the paired V-IoU
    difference (chosen − it: mean, low, high)."""

    row: AtlasRow
    p99_ms: float
    probed: dict[str, float]
    waiting: tuple[str, ...] = ()
    tied_with: tuple[str, tuple[float, float, float]] | None = None


@functools.lru_cache(maxsize=4)
def _resampler(strata: tuple[str, ...]) -> Resampler:
    return Resampler(strata)


def paired_viou(a: AtlasRow, b: AtlasRow) -> tuple[float, float, float] | None:
    """V-IoU of `a` − `b` on the same held-out trajectories with its 95 % paired interval (mean, low, high);
    None when either row lacks per-trajectory values or they come from different runs."""
    if not a.per_trajectory_viou or a.strata != b.strata or len(a.per_trajectory_viou) != len(b.per_trajectory_viou):
        return None
    return _resampler(a.strata).difference(a.per_trajectory_viou, b.per_trajectory_viou)


def tied_faster(row: AtlasRow, rows: list[AtlasRow]) -> list[tuple[AtlasRow, tuple[float, float, float]]]:
    """The rows faster than `row` in the atlas (p99) whose paired V-IoU difference to it holds 0 — as accurate,
    as far as the held-out set can tell — with that difference, fastest first."""
    ties = [(other, diff) for other in rows if other.atlas_p99_ms < row.atlas_p99_ms
            and (diff := paired_viou(other, row)) is not None and diff[1] <= 0.0 <= diff[2]]
    return sorted(ties, key=lambda tie: tie[0].atlas_p99_ms)


def choose_within_budget(rows: list[AtlasRow], budget_ms: float, measure: Callable[[AtlasRow], float],
                         progress=print) -> BudgetChoice:
    """The first of `rows` (most accurate first) whose `measure`d p99 plus its output's look-ahead (the centre and
    stitched outputs show a frame 200 / 467 ms late) fits `budget_ms` — or, when faster rows cannot be told
    apart from it (`tied_faster`), the fastest of those that fits; a setting whose look-ahead alone exceeds the
    budget is not probed. UserError when the budget is not a finite number > 0, or when nothing fits (naming
    the fastest setting probed and its p99 here)."""
    require_finite_positive("--budget-ms", budget_ms)
    probed: dict[str, float] = {}
    waiting: list[str] = []

    def fits(row: AtlasRow, note: str = "") -> bool:
        wait = row.setting.lookahead_ms
        progress(f"probe {row.name}: measuring here…")
        probed[row.name] = p99 = measure(row)
        ahead = f" + look-ahead {wait:.0f} ms" if wait else ""
        fit = p99 + wait <= budget_ms
        progress(f"probe {row.name}: p99 {p99:.2f} ms{ahead} ({'fits' if fit else 'over'} {budget_ms:g} ms){note}")
        return fit

    for row in rows:
        if row.setting.lookahead_ms >= budget_ms:
            waiting.append(row.name)
            continue
        if not fits(row):
            continue
        for tie, diff in tied_faster(row, rows):
            note = f"; as accurate as {row.name}: paired ΔV-IoU {diff[0]:+.3f} [{diff[1]:+.3f}, {diff[2]:+.3f}]"
            if tie.setting.lookahead_ms < budget_ms and fits(tie, note):
                return BudgetChoice(tie, probed[tie.name], probed, tuple(waiting), (row.name, diff))
        return BudgetChoice(row, probed[row.name], probed, tuple(waiting))
    if not probed:
        raise UserError(f"no setting fits {budget_ms:g} ms: every setting of the atlas waits longer for its output")
    fastest = min(probed, key=probed.get)
    raise UserError(f"no setting fits {budget_ms:g} ms on this machine: the fastest, {fastest}, took p99 "
                    f"{probed[fastest]:.2f} ms here")


def choice_line(choice: BudgetChoice, budget_ms: float) -> str:
    """Why the setting was chosen, in one line."""
    tied = choice.tied_with[0] if choice.tied_with else None
    better = [name for name, p99 in choice.probed.items()
              if name not in (choice.row.name, tied) and math.isfinite(p99)]
    beaten = f"; {len(better)} more accurate setting(s) took longer" if better else ""
    beaten += (f"; {len(choice.waiting)} more accurate setting(s) show their frame too late (look-ahead)"
               if choice.waiting else "")
    if choice.tied_with:
        name, (mean, low, high) = choice.tied_with
        beaten += (f"; as accurate as {name} (paired ΔV-IoU {mean:+.3f} [{low:+.3f}, {high:+.3f}] on the atlas's "
                   "held-out trajectories) and faster")
    beaten = beaten or "; the most accurate setting"
    wait = choice.row.setting.lookahead_ms
    ahead = f" + look-ahead {wait:.0f} ms" if wait else ""
    return (f"setting {choice.row.name}: {choice.row.accuracy_line()}; p99 {choice.p99_ms:.2f} ms here{ahead}, "
            f"within {budget_ms:g} ms{beaten}")
