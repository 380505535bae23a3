"""Scoring: the official metrics (batch and running), the official evaluation protocol over a split, and
the speed/accuracy bench of every engine setting. Imports `devices`, `inference.model`, `inference.engine` and
`inference.training`."""
