"""Renamed public names keep working for a while, with a ``DeprecationWarning``.

:func:`deprecated_names` serves renamed module attributes (a module ``__getattr__``); :func:`renamed_keywords`
accepts renamed keyword arguments.
"""

from __future__ import annotations

import functools
import importlib
import warnings
from collections.abc import Callable, Mapping
from typing import Any, ParamSpec, TypeVar

__all__ = ["deprecated_names", "renamed_keywords"]

P = ParamSpec("P")
R = TypeVar("R")


def deprecated_names(
    module: str, renamed: Mapping[str, tuple[str, Any] | str], *, stacklevel: int = 2
) -> Callable[[str], Any]:
    """A module ``__getattr__`` serving each old name of ``renamed`` with a ``DeprecationWarning``.

    Python calls a module's ``__getattr__`` only for names the module does not define, so current names cost nothing.

    Args:
        module: the module's ``__name__`` (for messages).
        renamed: ``{old_name: (new name as users should write it, the object)}``, or ``{old_name: new dotted
            name}`` alone, imported on first use (for a lazy package, whose objects are not loaded yet).
        stacklevel: the warning's ``stacklevel`` (3 when another ``__getattr__`` calls this one), so that it names
            the user's line.

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
        >>> with warnings.catch_warnings(record=True):
        ...     warnings.simplefilter("always")
        ...     deprecated_names("pkg", {"old_sqrt": "math.sqrt"})("old_sqrt")(4.0)
        2.0
    """

    def module_getattr(name: str) -> Any:
        if name not in renamed:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        entry = renamed[name]
        if isinstance(entry, str):
            owner, _, attribute = entry.rpartition(".")
            new_name, obj = entry, getattr(importlib.import_module(owner), attribute)
        else:
            new_name, obj = entry
        warnings.warn(
            f"{module}.{name} is deprecated: use {new_name} (same behaviour)", DeprecationWarning, stacklevel=stacklevel
        )
        return obj

    return module_getattr


def renamed_keywords(**renames: str) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """Decorate a function whose keywords were renamed (``old="new"``) so that the old names still work.

    A call with an old name warns (``DeprecationWarning``, pointing at the caller) and passes the value under the
    new name; giving both names is a ``TypeError``.

    Example:
        >>> import warnings
        >>> @renamed_keywords(n="count")
        ... def repeat(text: str, *, count: int = 1) -> str:
        ...     return text * count
        >>> with warnings.catch_warnings(record=True) as caught:
        ...     warnings.simplefilter("always")
        ...     repeat("ab", n=2), caught[0].category.__name__
        ('abab', 'DeprecationWarning')
    """

    def decorate(fn: Callable[P, R]) -> Callable[P, R]:
        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            for old, new in renames.items():
                if old not in kwargs:
                    continue
                if new in kwargs:
                    raise TypeError(f"{fn.__name__}(): got both {old}= (deprecated) and {new}=; pass {new}= only")
                warnings.warn(
                    f"{fn.__name__}({old}=...) is deprecated; use {new}=... instead", DeprecationWarning, stacklevel=2
                )
                kwargs[new] = kwargs.pop(old)
            return fn(*args, **kwargs)

        return wrapper

    return decorate
