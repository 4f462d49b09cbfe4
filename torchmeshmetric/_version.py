"""The package's version: one source, the installed distribution's metadata (``pyproject.toml``'s ``version``).

On the ground floor so that every module (the package root, the report writers) reads it without importing the
package root.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path

from torchmeshmetric._toml import tomllib

__all__ = ["__version__"]


def _read_version() -> str:
    """The installed version; in a source checkout that is not installed, ``pyproject.toml``'s."""
    try:
        return metadata.version("torchmeshmetric")
    except metadata.PackageNotFoundError:
        pyproject = Path(__file__).resolve().parent.parent / "pyproject.toml"
        try:
            return str(tomllib.loads(pyproject.read_text())["project"]["version"])
        except (OSError, KeyError, tomllib.TOMLDecodeError):
            return "0+unknown"


__version__: str = _read_version()
