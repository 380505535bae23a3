"""Hand pose estimated from a camera image (bare hands): MediaPipe's hand landmarks brought into WiLoR's camera
frame, the model's pose input, with handedness, smoothing and the hand-model file built at install time."""
