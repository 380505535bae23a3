"""Sources of samples: episode files, replay, the simulated rig and (later) live hardware adapters."""
