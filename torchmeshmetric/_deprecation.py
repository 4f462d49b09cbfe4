"""Deprecated keyword names that keep working: the old name is accepted with a ``DeprecationWarning``."""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

__all__ = ["renamed_keywords"]

P = ParamSpec("P")
R = TypeVar("R")


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
