"""The TouchAnything model and what runs it: `model/` (the official architecture, configs, checkpoints),
`engine/` (the streaming engine and its runtimes), `training/`, `evaluation/` (the official metric protocol,
bench). Researchers start from the front door, `import touchanything`."""
