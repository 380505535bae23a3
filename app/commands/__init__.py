"""One module per `touchanything` sub-command, each with `add_parser(commands)` and `run(args) -> int`. A
command imports `app.sessions` and anything below it, never another command (shared code goes to
`app.sessions`). At its top a command imports only what its options need; torch, OpenCV, PyAV, Rerun, the
engine, the model and the rest are imported inside the functions that use them, so that `--help` answers at
once (tests/timing/test_cli_startup.py keeps it so)."""
