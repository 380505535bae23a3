"""Training: the training config (official recipe), the trainer (single process or DDP), the tactile loss,
the clip dataset over HDF5 trajectories and the frozen-backbone feature cache. Imports `devices` and
`inference.model` (never `inference.engine`)."""
