"""One module per `touchanything` sub-command, each with `add_parser(commands)` and `run(args) -> int`. A
command imports `app.sessions` and anything below it, never another command (shared code goes to
`app.sessions`)."""
