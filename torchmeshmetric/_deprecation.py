"""Renamed public names keep working for a while: a module ``__getattr__`` that serves them with a warning."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["deprecated_names"]


def deprecated_names(module: str, renamed: Mapping[str, tuple[str, Any]]) -> Callable[[str], Any]:
    """A module ``__getattr__`` serving each old name of ``renamed`` with a ``DeprecationWarning``.

    Python calls a module's ``__getattr__`` only for names the module does not define, so current names cost nothing.

    Args:
        module: the module's ``__name__`` (for messages).
        renamed: ``{old_name: (new name as users should write it, the object)}``.

    Returns:
        The function to assign to the module's ``__getattr__``.

    Example:
        >>> import warnings
        >>> getattr_ = deprecated_names("pkg", {"old": ("pkg.new", 42)})
        >>> with warnings.catch_warnings(record=True) as caught:
        ...     warnings.simplefilter("always")
        ...     value = getattr_("old")
        >>> value, str(caught[0].message)
        (42, 'pkg.old is deprecated: use pkg.new (same behaviour)')
    """

    def module_getattr(name: str) -> Any:
        if name not in renamed:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        new_name, obj = renamed[name]
        warnings.warn(
            f"{module}.{name} is deprecated: use {new_name} (same behaviour)", DeprecationWarning, stacklevel=2
        )
        return obj

    return module_getattr
