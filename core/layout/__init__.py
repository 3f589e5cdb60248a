"""TODO package contract."""
