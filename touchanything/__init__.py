"""TouchAnything Live: bimanual pressure from egocentric video and hand pose, live and on recordings.

The front door for scripting the tool. The bundled model on the bundled sample:

    import touchanything as ta

    model = ta.load_model(ta.bundled_models()["nano"])
    engine = ta.StreamingEngine(model, ta.EngineConfig())
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
from touchanything.app.sessions.bundled import bundled_models, sample_episodes
from touchanything.devices.camera_pose.estimator import CameraPoseConfig, HandPoseEstimator
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.errors import DataError, UserError
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.devices.snapshot import VIEW_NAMES, Snapshot
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.inference.engine.engine_config import EngineConfig
from touchanything.inference.engine.live_engine import LiveEngine
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.evaluation import evaluate
from touchanything.inference.evaluation.metrics import ALL_METRICS, METRICS, MetricAccumulator, aggregate, compute_tactile_metrics
from touchanything.inference.evaluation.trajectory_prediction import predict_trajectory
from touchanything.inference.model.checkpoint import build_model, load_model, save_checkpoint
from touchanything.inference.model.model_config import PRESETS, ModelConfig, read_model_config
from touchanything.inference.model.touch_model import TouchAnything

__all__ = [
    # the model
    "load_model", "build_model", "save_checkpoint", "read_model_config", "ModelConfig", "PRESETS", "TouchAnything",
    "bundled_models",
    # running it frame by frame
    "StreamingEngine", "EngineConfig", "LiveEngine", "Snapshot", "Prediction", "VIEW_NAMES",
    # episodes
    "open_episode", "Episode", "ReplaySource", "ReplayConfig", "sample_episodes", "TactileLayout",
    # hand pose estimated from the camera (bare hands)
    "HandPoseEstimator", "CameraPoseConfig",
    # the official metrics and evaluation
    "compute_tactile_metrics", "MetricAccumulator", "aggregate", "METRICS", "ALL_METRICS", "predict_trajectory", "evaluate",
    # errors a user can act on
    "UserError", "DataError",
]
