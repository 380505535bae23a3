"""What ships with the code, found the way an installed package finds its files (`importlib.resources`): the
bundled models (`touchanything.models`: the checkout's `models/`), the speed/accuracy atlas of the bundled models
beside them (`models/atlas/engine.json`), and the sample episodes (`touchanything.sample`: the checkout's
`recordings/sample/`); and the default output folder. The same paths hold in an editable install (the
checkout's folders) and in a wheel (copies under the installed package); docs/layout.md."""
from __future__ import annotations

from importlib.resources import files
from pathlib import Path


def _package_folder(package: str) -> Path:
    """The folder of a data package (a wheel installs it unzipped, an editable install maps it to the checkout)."""
    return Path(str(files(package)))


MODELS_DIR = _package_folder("touchanything.models")
SAMPLE_DIR = _package_folder("touchanything.sample")
ATLAS_FILE = MODELS_DIR / "atlas" / "engine.json"
"""The committed atlas: every bundled model's settings on the held-out set (`touchanything bench`)."""
OUTPUT_DIR = Path("recordings")
"""Where every command, and the dashboard's Record and Screenshot buttons, write when not told where:
`recordings/` in the working directory (from the checkout, the git-ignored folder beside the sample)."""


def bundled_models() -> dict[str, Path]:
    """name → checkpoint of every model shipped under models/ (smallest first by file size)."""
    found = [p for p in MODELS_DIR.glob("*/best_model.pth")]
    return {p.parent.name: p for p in sorted(found, key=lambda p: p.stat().st_size)}


BASELINES = ("baseline_pose", "baseline_frames")
"""The bundled baselines reported beside the models (docs/findings.md): the single-frame pose MLP (trained on
black frames) and the small CNN on the frames with that MLP."""


def bundled_baselines() -> dict[str, Path]:
    """name → checkpoint of the bundled baselines that are present."""
    models = bundled_models()
    return {name: models[name] for name in BASELINES if name in models}


POSE_ONLY_SUFFIX = "_pose_only"


def pose_only_twin(checkpoint: Path) -> Path | None:
    """The checkpoint of the model's pose-only twin (the same design trained on black frames) when one lies
    beside it as `<model folder>_pose_only/` (models/nano → models/nano_pose_only), else None."""
    checkpoint = Path(checkpoint)
    twin = checkpoint.parent.with_name(checkpoint.parent.name + POSE_ONLY_SUFFIX) / checkpoint.name
    return twin if not checkpoint.parent.name.endswith(POSE_ONLY_SUFFIX) and twin.is_file() else None


def sample_episodes() -> list[Path]:
    """The bundled sample episodes (raw folders under recordings/sample)."""
    from touchanything.devices.episodes.episode_loader import find_raw_episodes  # imported where used: --help loads this module

    return find_raw_episodes(SAMPLE_DIR) if SAMPLE_DIR.is_dir() else []
