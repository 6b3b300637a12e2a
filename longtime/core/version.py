"""The package version, recorded in every run and in every kernel fingerprint."""
__version__ = "0.1.0"
