"""The package's version, for run records, done markers and ``monovo --version``."""

__version__ = "0.1.0"
