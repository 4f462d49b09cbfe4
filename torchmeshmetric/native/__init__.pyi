"""The names of ``torchmeshmetric.native``, which ``__init__.py`` imports on first use.

``torchmeshmetric._lazy`` reads the imports and ``__all__`` below at run time; mypy and IDEs read the types.
"""

# The public submodules (attributes of the package, as after a normal import).
from . import loader as loader
from .loader import EXTENSIONS, HOME, NativeBuildError, NativeExtension, build, load, ready, try_load

__all__ = ["EXTENSIONS", "HOME", "NativeBuildError", "NativeExtension", "build", "load", "ready", "try_load"]
