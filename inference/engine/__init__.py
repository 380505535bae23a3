"""The streaming engine: Snapshots in, `Prediction`s out, per-frame work cached in a ring (frame encoder,
window head, stitching), its settings (`EngineConfig`), the runtimes behind the `Runtime` protocol (torch,
ONNX Runtime) with the ONNX export, and the live latest-wins engine thread. Imports `devices` and
`inference.model` (never `inference.training`)."""
