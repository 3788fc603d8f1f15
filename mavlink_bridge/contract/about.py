"""The installed quadsitl version, for every command's ``--version``."""

from __future__ import annotations

import importlib.metadata
import platform


def version_text(prog: str) -> str:
    """``quadsitl sim 0.1.0 (Python 3.11.2)``; "not installed" when run from a tree never installed with pip."""
    try:
        version = importlib.metadata.version("quadsitl")
    except importlib.metadata.PackageNotFoundError:
        version = "(not installed: pip install -e .)"
    return f"{prog} {version} (Python {platform.python_version()})"
