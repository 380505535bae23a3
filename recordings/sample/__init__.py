"""The bundled sample episodes (raw EgoTouch folders), installed with the code as package data:
`touchanything.app.sessions.bundled` finds them."""
