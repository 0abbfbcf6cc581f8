"""The package version (one place; the CLI and stored files report it)."""
__version__ = "0.1.0"
