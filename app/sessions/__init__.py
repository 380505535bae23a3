"""Starting and stopping things in order: the engine, replay and live sessions behind the dashboard, scene
files and the rig they describe, the headless replay exporter, episode summaries, the model choice and
what ships bundled (models, sample episodes). Imports `devices`, `inference` and `viz` (dashboard included),
never `app.commands`."""
