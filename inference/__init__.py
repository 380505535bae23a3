"""TouchAnything model, checkpoints, streaming engine and evaluation."""
