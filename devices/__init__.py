"""Where samples come from and how they are stored. The root holds the records every layer shares (errors,
the `Snapshot` and view names, hand pose, tactile layout and pipeline, worker thread, rate meter); the
subpackages are `episodes/` (EgoTouch file formats), `hardware/` (the live device adapters), `rig/` (the rig
clock, recorder and replay) and `sim/` (the simulated rig). The root imports nothing else of the project."""
