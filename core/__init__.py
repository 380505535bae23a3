"""The shared records every layer sits on: errors (the one user-error path), the snapshot record and view names,
view sets, hand pose conventions, the tactile layout, the one output rule of every command that writes (and its
temporary files), input paths and the JSON reader. Imports nothing else of the project."""
