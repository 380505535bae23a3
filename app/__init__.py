"""The command line (`cli`, `commands/`) and the sessions that wire devices, engine and dashboard together
(`sessions/`). Everything else of the project may be imported here; nothing below imports `app`."""
