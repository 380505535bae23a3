"""TouchAnything Live: bimanual pressure from egocentric video and hand pose, live and on recordings.

The front door for scripting the tool. The bundled model on the bundled sample:

    import touchanything as ta

    model = ta.load_model(ta.bundled_models()["nano"])
    engine = ta.StreamingEngine(model, ta.EngineSetting("pico"))
    with ta.open_episode(ta.sample_episodes()[0]) as episode:
        replay = ta.ReplaySource(episode, ta.ReplayConfig(speed=None))
        predictions = [p for snapshot in replay for p in engine.step(snapshot)]
    ...

Any plain video works too: `open_episode("clip.mp4")` is an ego-only episode and
`ReplayConfig(pose_source="camera")` estimates the hands from its frames (`HandPoseEstimator`, bare hands).

Records: `Snapshot` in (one rig frame: images per view, 42 joints, raw pressure), `Prediction` out ((2, 21, 21)
pressure in [0, 1], NaN outside the `TactileLayout`). The subpackages (`touchanything.devices`, `.inference`,
`.viz`, `.app`) hold the rest; what is listed in `__all__` here is the public, stable surface.
"""
from __future__ import annotations

import importlib

_SOURCES = {
    "touchanything.app.sessions.bundled": ("bundled_models", "sample_episodes"),
    "touchanything.devices.camera_pose.estimator": ("CameraPoseConfig", "HandPoseEstimator"),
    "touchanything.devices.episodes.episode": ("Episode",),
    "touchanything.devices.episodes.episode_loader": ("open_episode",),
    "touchanything.core.errors": ("DataError", "UserError"),
    "touchanything.devices.rig.replay": ("ReplayConfig", "ReplaySource"),
    "touchanything.core.snapshot": ("VIEW_NAMES", "Snapshot"),
    "touchanything.core.tactile_layout": ("TactileLayout",),
    "touchanything.inference.engine.engine_setting": ("EngineSetting", "parse_setting"),
    "touchanything.inference.engine.live_engine": ("LiveEngine",),
    "touchanything.inference.engine.prediction": ("Prediction",),
    "touchanything.inference.engine.streaming_engine": ("StreamingEngine",),
    "touchanything.inference.evaluation.evaluation": ("evaluate",),
    "touchanything.inference.evaluation.metrics": ("ALL_METRICS", "METRICS", "MetricAccumulator", "aggregate", "compute_tactile_metrics"),
    "touchanything.inference.evaluation.trajectory_prediction": ("predict_trajectory",),
    "touchanything.inference.model.checkpoint": ("build_model", "load_model", "save_checkpoint"),
    "touchanything.inference.model.model_config": ("PRESETS", "ModelConfig", "read_model_config"),
    "touchanything.inference.model.touch_model": ("TouchAnything",),
}
"""module → the public names it holds: each is imported on first use, so that `import touchanything` (and the
command line, whose `--help` needs none of them) does not load torch."""
_MODULE = {name: module for module, names in _SOURCES.items() for name in names}

__all__ = [
    # the model
    "load_model", "build_model", "save_checkpoint", "read_model_config", "ModelConfig", "PRESETS", "TouchAnything",
    "bundled_models",
    # running it frame by frame
    "StreamingEngine", "EngineSetting", "parse_setting", "LiveEngine", "Snapshot", "Prediction", "VIEW_NAMES",
    # episodes
    "open_episode", "Episode", "ReplaySource", "ReplayConfig", "sample_episodes", "TactileLayout",
    # hand pose estimated from the camera (bare hands)
    "HandPoseEstimator", "CameraPoseConfig",
    # the official metrics and evaluation
    "compute_tactile_metrics", "MetricAccumulator", "aggregate", "METRICS", "ALL_METRICS", "predict_trajectory", "evaluate",
    # errors a user can act on
    "UserError", "DataError",
]


def __getattr__(name: str) -> object:
    """A public name, imported on first use."""
    if name not in _MODULE:
        raise AttributeError(f"module 'touchanything' has no attribute {name!r}")
    value = globals()[name] = getattr(importlib.import_module(_MODULE[name]), name)
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
