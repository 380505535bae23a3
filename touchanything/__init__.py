"""TouchAnything Live."""
