"""TouchAnything model, checkpoints, streaming engine and evaluation.

Public entry point: `inference.load_model(checkpoint_path, config_path=None)` → the model in eval mode.
"""
from touchanything.inference.model.checkpoint import load_model

__all__ = ["load_model"]
