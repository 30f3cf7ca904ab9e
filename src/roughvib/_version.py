"""The package version (kept in step with pyproject.toml); a leaf module every stage may import."""

__version__ = "0.1.0"
