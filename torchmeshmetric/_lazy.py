"""Lazy package namespaces: a package's public names are imported on first use (scikit-image's pattern).

Each package's ``__init__.py`` is one call, ``__getattr__, __dir__, __all__ = attach(__name__, __file__)``, and
its ``__init__.pyi`` beside it is the one list of the package's names: ``from .module import name`` lines (read
here, at run time, by :func:`lazy_loader.attach_stub`, and by mypy and IDEs for the types) and ``__all__``. So
``import torchmeshmetric`` imports neither torch nor torchmetrics; ``torchmeshmetric.Mesh`` imports the one module
that defines it (and what that module needs) on first access, and ``dir()``, ``from torchmeshmetric import *`` and
autocompletion see every name. ``EAGER_IMPORT=1`` in the environment imports everything at once (lazy_loader's
switch: handy to find a broken import).

What this adds to ``lazy_loader.attach_stub``: ``__all__`` is the stub's own list (lazy_loader's holds every
imported name); a submodule's names are bound when it is imported (:class:`_Package`); unknown names get Python's
usual ``AttributeError`` message.
"""

from __future__ import annotations

import ast
import os
import sys
import types
from collections.abc import Callable
from typing import Any

import lazy_loader

__all__ = ["attach"]


class _Package(types.ModuleType):
    """A lazy package that binds a submodule's names as soon as the submodule is imported, as eager imports would.

    The import system sets ``package.submodule`` when a submodule finishes loading (however it was imported); the
    names the stub takes from that submodule are bound then, to the objects it holds at that moment. Without that,
    a name would be bound on its first access, and see whatever the submodule holds by then (a test's patch of
    ``pipeline.default_register`` would leak into ``evaluation.default_register`` and outlive the test). A function
    named like its own module (``mpeg.comparison.mpeg_metrics``) keeps the name: the submodule does not replace it.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        binds: dict[str, list[str]] = self.__dict__.get("__lazy_binds__", {})
        if name in binds and value is sys.modules.get(f"{self.__name__}.{name}"):
            names = vars(value)
            for attr in binds[name]:
                if attr in names:  # a lazy subpackage holds only the names already used
                    self.__dict__[attr] = names[attr]
            if name in binds[name]:
                return  # the function of the same name stays the package's attribute
        super().__setattr__(name, value)


def _read_stub(stub: str) -> tuple[list[str], dict[str, list[str]]]:
    """The ``__all__ = [...]`` list of a stub file, and the names it imports from each direct submodule."""
    with open(stub) as f:
        tree = ast.parse(f.read(), stub)
    public: list[str] | None = None
    binds: dict[str, list[str]] = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            public = list(ast.literal_eval(node.value))
        elif isinstance(node, ast.ImportFrom) and node.module and "." not in node.module:
            binds.setdefault(node.module, []).extend(alias.name for alias in node.names)
    if public is None:
        raise ImportError(f"{stub}: no __all__ list")
    return public, binds


def attach(package: str, file: str) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """The ``__getattr__``, ``__dir__`` and ``__all__`` of a package whose names ``__init__.pyi`` lists.

    Args:
        package: the package's ``__name__``.
        file: the package's ``__file__`` (``__init__.py``; the stub is ``__init__.pyi`` beside it).

    Returns:
        The module-level ``__getattr__`` (PEP 562) that imports a listed name's module on first access and caches
        the name in the package, ``__dir__`` (the listed names, public submodules included, and what the package
        already holds) and ``__all__`` (the stub's ``__all__``, what ``from package import *`` takes).

    Raises:
        ImportError: the stub lists in ``__all__`` a name it does not import (a packaging mistake, caught on import).

    Example:
        >>> import torchmeshmetric.stats as stats
        >>> "DistanceStatistics" in stats.__all__ and "DistanceStatistics" in dir(stats)
        True
        >>> stats.no_such_name
        Traceback (most recent call last):
        ...
        AttributeError: module 'torchmeshmetric.stats' has no attribute 'no_such_name'
    """
    load, _, names = lazy_loader.attach_stub(package, file)
    stub = f"{os.path.splitext(file)[0]}.pyi"
    public, binds = _read_stub(stub)
    module = sys.modules[package]
    module.__dict__["__lazy_binds__"] = binds
    if type(module) is not _Package:
        module.__class__ = _Package  # replaces lazy_loader's guard of same-named functions, which _Package keeps
    unknown = sorted(set(public) - set(names))
    if unknown:
        raise ImportError(f"{stub}: __all__ lists {unknown}, which the stub does not import")
    listed = frozenset(names)

    def module_getattr(name: str) -> Any:
        if name in listed:
            return load(name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def module_dir() -> list[str]:
        return sorted(listed | set(vars(sys.modules[package])))

    return module_getattr, module_dir, public
