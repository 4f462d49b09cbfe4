"""One TOML manifest reader: the campaign manifests' (``evaluation.campaign``, ``mpeg.ctc.manifest``) file step.

Only the standard library (and ``tomli`` on Python 3.10) is imported.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10 installs tomli (pyproject's dependencies)
    import tomli as tomllib

__all__ = ["kind_name", "read_manifest", "tomllib"]


def read_manifest(path: str | os.PathLike[str], what: str, error: type[ValueError]) -> dict[str, Any]:
    """The TOML file ``path`` as a dict; a missing, unreadable or malformed file raises ``error`` naming it.

    Args:
        path: the manifest file.
        what: how messages name it (``"campaign manifest"``): ``"{what} 'path': ..."``.
        error: the manifest's error type (a ``ValueError``).

    Raises:
        error: no such file, an unreadable file, bad UTF-8 or bad TOML (the parser's message, with line and column).

    Example:
        >>> read_manifest("no/such.toml", "campaign manifest", ValueError)
        Traceback (most recent call last):
        ...
        ValueError: campaign manifest 'no/such.toml': no such file
    """
    file = Path(path)
    try:
        return tomllib.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise error(f"{what} {str(file)!r}: no such file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise error(f"{what} {str(file)!r}: {exc}") from None


#: How messages name the TOML value types a manifest key may hold.
_KIND_NAMES = {
    bool: "true or false",
    int: "an integer",
    float: "a number",
    str: "a string",
    list: "a list",
    dict: "a table",
}


def kind_name(kinds: type | tuple[type, ...]) -> str:
    """The TOML value type(s) ``kinds`` in words, for "'key' must be ..." messages.

    Example:
        >>> kind_name((int, float))
        'an integer or a number'
    """
    kinds = kinds if isinstance(kinds, tuple) else (kinds,)
    return " or ".join(_KIND_NAMES.get(k, f"a {k.__name__}") for k in kinds)
