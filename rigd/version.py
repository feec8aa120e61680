"""rigd's version, from the installed package's metadata (pyproject.toml)."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version


def software_version() -> str:
    """The installed rigd's version, or "unknown" when running from a source tree that was never installed."""
    try:
        return version("rigd")
    except PackageNotFoundError:
        return "unknown"
