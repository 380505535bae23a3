"""The `--setting` option of `replay`, `live` and `demo`, and `bench --budget-ms`: a setting of the atlas by name
(`nano/onnx-int8/all`), or `auto` with `--budget-ms MS` — the most accurate setting whose p99 latency, probed on
this machine, fits MS (`inference.evaluation.atlas`). Either way the command says which setting runs and why."""
from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from touchanything.app.sessions.budget_watch import BudgetWatch
from touchanything.app.sessions.bundled import ATLAS_FILE, SAMPLE_DIR, bundled_models
from touchanything.app.sessions.engine_choice import ModelChoice, is_bundled
from touchanything.core.errors import UserError, require_finite_positive
from touchanything.inference.engine.engine_setting import NAME_HELP
from touchanything.inference.evaluation.atlas import (
    PROBE_FRAMES,
    AtlasRow,
    choice_line,
    choose_within_budget,
    find_row,
    probe_p99,
    read_atlas,
    rows_for,
)
from touchanything.inference.model.model_card import read_card
from touchanything.viz.model_accuracy import ModelAccuracy, model_accuracy

PROBE_CLIP_FRAMES = 60
ENGINE_OPTIONS = ("checkpoint", "config", "runtime", "precision", "views", "onnx")
"""The options a `--setting` decides (a command given both is refused)."""


def add_setting_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--setting", metavar="NAME",
                        help=f"run a setting of the speed/accuracy atlas ({NAME_HELP}), or auto with --budget-ms: the most "
                             "accurate one whose p99 latency fits, probed on this machine")
    parser.add_argument("--budget-ms", type=float, metavar="MS", help="with --setting auto: the per-frame latency budget")
    parser.add_argument("--atlas", type=Path, default=ATLAS_FILE,
                        help="with --setting: the atlas (default: the committed models/atlas/engine.json)")


@dataclass(frozen=True)
class PickedSetting:
    """The atlas row that runs, its checkpoint here, its p99 probed here (None when named, not probed), and the
    line that says which and why."""

    row: AtlasRow
    checkpoint: Path
    p99_ms: float | None
    line: str
    budget_ms: float | None = None

    def model_choice(self, device: str) -> ModelChoice:
        """The row's setting, every knob of it, on `device`, with its checkpoint here."""
        return ModelChoice(self.checkpoint, dataclasses.replace(self.row.setting, device=device))

    def budget_watch(self) -> BudgetWatch | None:
        """What watches the run keep the budget the setting was chosen for (None: a named setting)."""
        if self.budget_ms is None or self.p99_ms is None:
            return None
        return BudgetWatch(self.row.name, self.budget_ms, self.p99_ms)


def running_accuracy(choice: ModelChoice, rows: Sequence[AtlasRow]) -> ModelAccuracy:
    """The one held-out accuracy said of the running model (`viz.model_accuracy`): from the atlas `rows` (those
    of the models here, `display_atlas`) when its checkpoint is a bundled model's, else from its card."""
    return model_accuracy(choice.setting, rows if is_bundled(choice.checkpoint) else (), read_card(choice.checkpoint))


def display_atlas(atlas: Path) -> tuple[tuple[AtlasRow, ...], str]:
    """The atlas rows of the models here, for the dashboard's atlas panel, or none and the reason (a missing,
    damaged or other-weights atlas leaves the panel empty; it never stops a session)."""
    try:
        return tuple(rows_for(read_atlas(atlas), bundled_models(), atlas)), ""
    except UserError as exc:
        return (), str(exc)


def _checkpoints(model_folders: list[Path] | None) -> dict[str, Path]:
    if model_folders:
        return {Path(f).name: Path(f) / "best_model.pth" for f in model_folders}
    return bundled_models()


@dataclass(frozen=True)
class SettingRequest:
    """A checked `--setting`: the atlas rows of the models here (most accurate first), their checkpoints, and
    either the named row or the budget of `auto`."""

    atlas: Path
    rows: list[AtlasRow]
    checkpoints: dict[str, Path]
    named: AtlasRow | None = None
    budget_ms: float | None = None

    @property
    def inputs(self) -> tuple[Path, ...]:
        """The checkpoints the setting may run (the command's inputs, never written)."""
        models = {self.named.setting.model} if self.named else {row.setting.model for row in self.rows}
        return tuple(self.checkpoints[m] for m in sorted(models))

    def pick(self, device: str, quick: bool = True) -> PickedSetting:
        """The named row, or the most accurate one whose p99, probed here on the bundled sample's first episode,
        fits the budget (UserError when none does)."""
        if self.named is not None:
            row = self.named
            return PickedSetting(row, self.checkpoints[row.setting.model], None,
                                 f"setting {row.name}: {row.accuracy_line()}; p99 {row.atlas_p99_ms:.2f} ms where the "
                                 "atlas was measured")
        # imported where used: --help loads this module
        from touchanything.inference.evaluation.bench_data import episode_paths, first_latency_clip
        from touchanything.inference.model.checkpoint import load_model

        clip = first_latency_clip(episode_paths(SAMPLE_DIR), PROBE_CLIP_FRAMES)
        models = {}

        def measure(row: AtlasRow) -> float:
            name = row.setting.model
            models[name] = models.get(name) or load_model(self.checkpoints[name])
            return probe_p99(models[name], row.setting, clip, PROBE_FRAMES[quick], device, self.checkpoints[name])

        choice = choose_within_budget(self.rows, self.budget_ms, measure, progress=lambda line: print(line, flush=True))
        return PickedSetting(choice.row, self.checkpoints[choice.row.setting.model], choice.p99_ms,
                             choice_line(choice, self.budget_ms), self.budget_ms)


def budget_request(atlas: Path, budget_ms: float, model_folders: list[Path] | None = None) -> SettingRequest:
    """`auto` within `budget_ms` over the atlas rows of the models here; UserError (one line) for a bad budget or
    atlas."""
    require_finite_positive("--budget-ms", budget_ms)
    checkpoints = _checkpoints(model_folders)
    return SettingRequest(atlas, rows_for(read_atlas(atlas), checkpoints, atlas), checkpoints, budget_ms=budget_ms)


def setting_request(args: argparse.Namespace) -> SettingRequest | None:
    """A command's `--setting`, checked before any work (None without one); UserError when it is combined with an
    option it decides, or `--budget-ms` goes without `--setting auto`."""
    if args.setting is None:
        if args.budget_ms is not None:
            raise UserError("--budget-ms needs --setting auto")
        return None
    given = [f"--{o}" for o in ENGINE_OPTIONS if getattr(args, o, None) is not None]
    if given:
        raise UserError(f"--setting decides the model, runtime, precision and views; drop {', '.join(given)}")
    if args.setting == "auto":
        if args.budget_ms is None:
            raise UserError("--setting auto needs --budget-ms MS (the per-frame latency budget)")
        return budget_request(args.atlas, args.budget_ms)
    if args.budget_ms is not None:
        raise UserError("--budget-ms goes with --setting auto, not with a named setting")
    checkpoints = bundled_models()
    rows = rows_for(read_atlas(args.atlas), checkpoints, args.atlas)
    return SettingRequest(args.atlas, rows, checkpoints, named=find_row(rows, args.setting, args.atlas))


def picked_setting(request: SettingRequest | None, device: str | None) -> PickedSetting | None:
    """The request's setting (None without one), printed with why it was chosen."""
    if request is None:
        return None
    picked = request.pick(device or "auto")
    print(picked.line)
    return picked
