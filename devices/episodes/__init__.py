"""The EgoTouch file formats: raw episode folders (videos, JSON-lines streams, pressure grids, masks, quality,
intrinsics), HDF5 trajectories, the `Episode` both open as, the crash-safe episode writer, raw → HDF5
conversion and `split.json`. Imports only the `devices` root (never `devices.hardware`)."""
