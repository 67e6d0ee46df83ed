"""The package version (one definition: the facade re-exports it, the USD writer records it)."""

__version__ = "0.1.0"
