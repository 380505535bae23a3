"""Where samples come from and how they are stored, on the shared records of `touchanything.core`. The root holds
device helpers (the glove pipeline from raw bytes to grids, the worker thread, the rate meter, a C library's stderr
captured); the subpackages are `camera_pose/` (hands estimated from a camera), `episodes/` (EgoTouch file
formats), `hardware/` (the live device adapters), `rig/` (the rig clock, recorder and replay) and `sim/` (the
simulated rig). The root imports only `touchanything.core`."""
