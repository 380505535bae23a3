"""The TouchAnything model, checkpoint-compatible with the official release: the architecture (ViT backbone,
multi-view, temporal, pose, fusion, decoder), presets and the official config reader, checkpoints, and the
input preprocessing. Imports only from `devices`."""
